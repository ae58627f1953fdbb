"""Calibration: programs that produce known engagements with their plan (`plan`), and fits of cutting
coefficients (`cuts`) and machine constants (`machine_fit`) from logs or tables of steady cuts."""

"""Chatter stability: the tool-tip frequency response (`frf`), stability lobes (`lobes`) and the tap test
(`tap`: modal parameters from a hammer test, the chatter frequency from a recording)."""

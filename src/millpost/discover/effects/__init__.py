"""Candidate effects: one module each, registered in the ``millpost.effects`` entry-point group."""

"""Panoramic reformat and cross-section drawing (matplotlib), shared by CLI, GUI and report."""

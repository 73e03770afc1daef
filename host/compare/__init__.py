"""Measurement against the ANCF model: material-point tracks in metres, errors, parameter identification."""

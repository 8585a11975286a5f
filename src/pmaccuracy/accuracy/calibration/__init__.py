"""Kinematic calibration and compensation (issue 23): error parameters, identification, identifiability,
pose planning, compensation and a virtual calibration experiment."""

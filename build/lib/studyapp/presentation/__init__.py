"""Presentation layer: the only part of studyapp that may import PsychoPy (in psychopy_window)."""

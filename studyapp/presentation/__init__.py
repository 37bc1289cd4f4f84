"""Presentation layer: the only part of studyapp that may import PsychoPy (psychopy_window and its parts:
window, text, loading, eyetracker, live_window)."""

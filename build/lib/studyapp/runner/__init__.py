"""The study runner: protocols, schedules, sessions and the simulated observer.

Nothing here imports PsychoPy; a window is reached only through :class:`studyapp.presentation.base.Presenter`.
"""

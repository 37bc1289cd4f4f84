"""studyapp: perceptual user studies of foveated rendering (CLI, sessions, presentation, simulated observer)."""

__version__ = "0.1.0"

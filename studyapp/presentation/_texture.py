"""A GL texture handed to PsychoPy as an image (shared by the still-image window and the live loop)."""


class TextureRef:
    """Hands an already uploaded GL texture to ``ImageStim.image`` (PsychoPy's path for movie/camera
    frames)."""

    isLumImage = False

    def __init__(self, tex_id):
        self.colorTexture = tex_id

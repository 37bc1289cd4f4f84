"""Text layout in the window: instructions and messages, the black interval's text, and the overlays drawn
over a stimulus (fixation mark, stimulus label and picks, "practice" tag, the reference's label, the key reminder,
the question in the margin below the stimulus).

Text is laid out for the window: a height that reads at the viewing distance of the display (about 1/36 of its
height), wrapped inside it, and shrunk until the whole text fits (:meth:`TextLayout.fit_text`), so no text is
ever clipped by the window. PsychoPy's ``visual`` module is handed in by the window that owns the stimuli.
"""

from __future__ import annotations

from data_schema.geometry import Placement

from .base import TrialDisplay, key_reminder_text
from .trial_logic import stim_labels


def progress_text(trial: TrialDisplay) -> str:
    """The trial's place in the session as shown in dim text: "3 / 96", "practice" or nothing."""
    if trial.kind == "practice":
        return "practice"
    if trial.progress is None:
        return ""
    k, n = trial.progress
    return f"{k} / {n}"


def _set_text(stim, text: str) -> None:
    """Set a TextStim's text only when it changes (a change re-lays out the text, too slow for every
    frame)."""
    if stim.text != text:
        stim.text = text


class TextLayout:
    """The window's text and overlay stimuli and how they are laid out (see the module docstring).

    Parameters
    ----------
    win, visual : the PsychoPy window and ``psychopy.visual``.
    text_height_px : the text height; None: ``max(14, min(40, round(window height / 36)))``.
    fixation_rgb, fixation_size_px, fixation_line_px : the fixation cross (0-255 RGB, None: no mark; arm
        length and line width in window pixels).
    show_labels : draw "A"/"B" (2AFC) or "1".."N" (preference) in the top-left corner while switching.
    """

    def __init__(self, win, visual, *, text_height_px: int | None, fixation_rgb, fixation_size_px: int,
                 fixation_line_px: int, show_labels: bool):
        self.win = win
        self.show_labels = show_labels
        self.fixation_rgb = fixation_rgb
        ww, wh = (int(v) for v in win.size)
        h = text_height_px or max(14, min(40, round(wh / 36)))
        self.text_h = h
        self._text = visual.TextStim(win, text="", height=h, color=(0.8, 0.8, 0.8), wrapWidth=ww * 0.9,
                                     units="pix")
        self._dim = visual.TextStim(win, text="", height=h * 0.75, color=(-0.3, -0.3, -0.3), units="pix",
                                    wrapWidth=ww * 0.9, pos=(0, -wh / 2 + h))
        self._question = visual.TextStim(win, text="", height=h, color=(0.8, 0.8, 0.8), units="pix",
                                         wrapWidth=ww * 0.9)
        self._corner = visual.TextStim(win, text="", height=h, color=(1, 1, 1), units="pix",
                                       anchorHoriz="left", alignText="left", anchorVert="top", pos=(-ww / 2 + 8, wh / 2 - 8))
        # Overlays over the stimulus: the reference's label (top centre), "practice" (top right) and the key
        # reminder on a dark band (bottom or top), readable over any stimulus.
        self._label = visual.TextStim(win, text="", height=h, color=(1, 1, 1), units="pix", anchorVert="top",
                                      pos=(0, wh / 2 - 8), wrapWidth=ww * 0.6)
        self._tag = visual.TextStim(win, text="practice", height=h, color=(1, 0.8, 0.2), units="pix",
                                    anchorHoriz="right", alignText="right", anchorVert="top",
                                    pos=(ww / 2 - 8, wh / 2 - 8))
        self._reminder = visual.TextStim(win, text="", height=h, color=(0.8, 0.8, 0.8), units="pix",
                                         wrapWidth=ww * 0.95)
        self._reminder_band = visual.Rect(win, width=ww, height=round(h * 1.6), units="pix",
                                          fillColor=(-1, -1, -1), lineColor=None, lineWidth=0, opacity=0.7)
        self._fix = []
        if fixation_rgb is not None:
            arm, line = fixation_size_px, fixation_line_px
            for w, hh in ((arm, line), (line, arm)):
                self._fix.append(visual.Rect(win, width=w, height=hh, units="pix", fillColor=fixation_rgb,
                                             lineColor=None, colorSpace="rgb255", lineWidth=0))

    def fit_text(self, stim, text: str, max_h: float) -> None:
        """Set ``text`` on ``stim`` at the window's text height, shrunk until the wrapped text is at most
        ``max_h`` pixels high (never clipped by the window). Re-laid out only when the text changes."""
        if stim.text == text:
            return
        stim.height = self.text_h * (0.75 if stim is self._dim else 1.0)
        stim.text = text
        while text and stim.boundingBox[1] > max_h and stim.height > 6:
            stim.height = stim.height * 0.85
            stim.text = text + " "  # force a new layout at the new height
            stim.text = text

    def draw_text(self, text: str, dim: str = "") -> None:
        """``text`` centred (at most 80 % of the window high) and ``dim`` in small dim text at the bottom."""
        wh = int(self.win.size[1])
        self.fit_text(self._text, text, 0.8 * wh)
        self._text.draw()
        if dim:
            self.fit_text(self._dim, dim, 2.5 * self.text_h)
            self._dim.pos = (0, -wh / 2 + 0.5 * self._dim.boundingBox[1] + 4)
            self._dim.draw()

    def text_record(self) -> dict:
        """The main text's height and box as last laid out, and the window size (stored per trial)."""
        return {"text_height_px": float(self._text.height),
                "text_box_px": [float(v) for v in self._text.boundingBox],
                "window_px": [int(v) for v in self.win.size]}

    def draw_question_in_margin(self, trial: TrialDisplay, placement: Placement) -> None:
        """Draw ``trial.question`` centred in the margin below the stimulus, above the key reminder's band at
        the bottom of the window, if that margin is at least 2 lines high (never over the stimulus; the
        question also shows in the black interval before each trial and after a sequence)."""
        bottom_band = trial.key_reminder == "bottom" and key_reminder_text(trial)
        below = float(self._reminder_band.height) if bottom_band else 0.0
        question = trial.question
        margin = placement.win_h - (placement.top + placement.size[1]) - below
        if question and margin >= 2 * self.text_h:
            self.fit_text(self._question, question, margin)
            self._question.pos = (0, -placement.win_h / 2.0 + below + margin / 2.0)
            self._question.draw()

    def draw_overlay(self, trial: TrialDisplay, current: int, picks: list, placement: Placement) -> None:
        """The fixation mark (at ``trial.fixation_px`` of the stimulus image placed by ``placement``), the key
        reminder and the reference's label, the label of stimulus ``current`` with the ``picks`` so far, and
        the "practice" tag."""
        if trial.fixation_px is not None and self.fixation_rgb is not None:
            fx, fy = placement.image_to_pix(*trial.fixation_px)
            for r in self._fix:
                r.pos = (fx, fy)
                r.draw()
        self._draw_reminder(trial)  # first: a top band must not cover the corner label or the practice tag
        labels = stim_labels(trial)
        if self.show_labels and len(labels) > 1:
            picked = ("  picked: " + ", ".join(labels[int(p)] for p in picks)) if picks else ""
            _set_text(self._corner, labels[current] + picked)
            self._corner.draw()
        if trial.kind == "practice":
            self._tag.draw()

    def _draw_reminder(self, trial: TrialDisplay) -> None:
        """The key reminder band (``trial.key_reminder``) and, below a top band, the reference's label."""
        wh = int(self.win.size[1])
        text = key_reminder_text(trial) if trial.key_reminder != "off" else ""
        band_h = float(self._reminder_band.height)
        if text:
            _set_text(self._reminder, text)
            y = -wh / 2 + band_h / 2 if trial.key_reminder == "bottom" else wh / 2 - band_h / 2
            self._reminder_band.pos = self._reminder.pos = (0, y)
            self._reminder_band.draw()
            self._reminder.draw()
        if trial.label:
            _set_text(self._label, trial.label)
            self._label.pos = (0, wh / 2 - 8 - (band_h if text and trial.key_reminder == "top" else 0))
            self._label.draw()

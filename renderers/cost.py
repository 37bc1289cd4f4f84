"""Device-independent cost of a renderer's frame, and of its ground truth, over a ladder of foveation strengths.

The cost axis of issue 28's perceptual Pareto front: what a frame of ``renderer`` with ``params`` costs on
``scene`` at ``width x height``, counted, not timed, so that it is the same on every machine and every run:

* ``shading_points`` — points shaded (primary hits; a log-polar renderer's hits in its LP buffer),
* ``rays_primary`` — primary rays (a log-polar renderer traces one per LP pixel on or bordering the display),
* ``rays_shadow`` — shadow rays cast,
* ``light_samples`` — light samples drawn (the lightcuts renderers; 0 for the others),
* ``lp_pixels`` — shaded pixels of the LP buffer (seed 001's shading-point count, Fig 4; 0 without one).

Each count is read from the stats of an actual render (:func:`renderers.registry.render`) of that frame: the
counts are deterministic (the stochastic renderers draw from their ``seed`` parameter), so the same inputs give
the same table. A frame is rendered once per process (memo by its stimulus cache key) and, with ``cache_dir``,
once ever: the frame goes through the stimulus cache (:func:`renderers.stimuli.render_stimulus`), so a ladder that
``studyapp prepare`` rendered for a study costs nothing more. Render at the study's size (the counts of GT and
LaFR/LMFR grow with the pixels; VaFR's with the default acuity curve hardly do).
"""

from __future__ import annotations

import json
from pathlib import Path

from data_schema.errors import UserError

#: The counts of a frame, in the order of the table's columns.
COUNTS = ("shading_points", "rays_primary", "rays_shadow", "light_samples", "lp_pixels")
#: The prefix of the reference's counts in :func:`cost_table`.
REFERENCE_PREFIX = "gt_"

_MEMO: dict[str, dict[str, int]] = {}


def ground_truth_of(renderer: str) -> str:
    """The ground truth a renderer approximates: ``sl_gt`` for the lightcuts renderers (their strength lowers
    light samples), ``gt`` for the others."""
    from .registry import foveation_strength, get

    get(renderer)  # an unknown name: one line
    spec = foveation_strength(renderer)
    return "sl_gt" if spec is not None and spec.count == "light_samples" else "gt"


def frame_counts(scene, renderer: str, params: dict | None, width: int, height: int, gaze=None,
                 camera: dict | None = None, cache_dir: Path | None = None) -> dict[str, int]:
    """The counts (:data:`COUNTS`) of one frame, from its render's stats.

    Parameters
    ----------
    scene : str, Path or Scene
        A built-in scene, a scene file or a Scene.
    renderer : str
        A registered renderer.
    params : dict, optional
        Its parameters (defaults filled in, checked: a bad value is a one-line :class:`UserError`).
    width, height : int
        The frame's size in pixels.
    gaze : (x, y), optional
        Gaze in pixels (default the centre).
    camera : dict, optional
        Camera overrides, e.g. ``{"fov_y": ...}`` from the protocol's display (as its stimuli have).
    cache_dir : Path, optional
        The stimulus cache to read the frame's stats from, or to render it into (``None``: render in process).

    Returns
    -------
    dict
        ``{count: int}`` for every name of :data:`COUNTS` (0 where the renderer has no such work).
    """
    from .stimuli import frame_request, render_entry, render_stimulus

    request = frame_request(scene, renderer, params, width, height, gaze, camera)
    if request.key not in _MEMO:
        if cache_dir is not None:
            png = render_stimulus(scene, renderer, params, width, height, request.gaze, camera, Path(cache_dir))
            stats = json.loads(png.with_suffix(".json").read_text())
        else:
            stats = json.loads(render_entry(request).stats_json)
        _MEMO[request.key] = {k: int(stats.get(k) or 0) for k in COUNTS}
    return dict(_MEMO[request.key])


def cost_table(scene, renderer: str, levels, width: int, height: int, *, params: dict | None = None,
               reference: str | None = None, reference_params: dict | None = None, gaze=None,
               camera: dict | None = None, cache_dir: Path | None = None):
    """The counts of ``renderer`` at each foveation level of a ladder, beside its ground truth's.

    Parameters
    ----------
    scene, width, height, gaze, camera, cache_dir
        As :func:`frame_counts` (the same for every row and for the reference).
    renderer : str
        A renderer with a foveation strength (:func:`renderers.registry.foveation_strength`).
    levels : sequence of float
        Values of its strength parameter (each checked against the declared range).
    params : dict, optional
        Its other parameters (the strength parameter, if given, is replaced by each level).
    reference : str, optional
        The ground truth (default :func:`ground_truth_of`), rendered once with ``reference_params``.

    Returns
    -------
    pandas.DataFrame
        One row per level, weakest foveation first: ``scene``, ``renderer``, ``param``, ``level``, ``width``,
        ``height``, ``reference``, the counts of :data:`COUNTS`, the reference's as ``gt_<count>``, and ``work``,
        ``gt_work``, ``work_ratio``: the count the strength lowers (``StrengthSpec.count``), the reference's, and
        their ratio (NaN where the reference's is 0).
    """
    import pandas as pd

    from .catalog import resolve
    from .registry import foveation_strength

    spec = foveation_strength(renderer)
    if spec is None:
        raise UserError(f"renderer {renderer!r} has no foveation strength: it is a ground truth")
    levels = list(levels)
    if not levels:
        raise UserError(f"levels of {renderer}.{spec.param} are empty: give at least one")
    levels = spec.weakest_first([spec.range.check(f"{renderer}.{spec.param}", v) for v in levels])
    reference = reference or ground_truth_of(renderer)
    name = resolve(scene).name
    gt = frame_counts(scene, reference, reference_params, width, height, gaze, camera, cache_dir)
    rows = []
    for level in levels:
        counts = frame_counts(scene, renderer, {**(params or {}), spec.param: level}, width, height, gaze, camera,
                              cache_dir)
        work, gt_work = counts[spec.count], gt[spec.count]
        rows.append({"scene": name, "renderer": renderer, "param": spec.param, "level": level, "width": int(width),
                     "height": int(height), "reference": reference, **counts,
                     **{REFERENCE_PREFIX + k: v for k, v in gt.items()}, "work": work, "gt_work": gt_work,
                     "work_ratio": work / gt_work if gt_work else float("nan")})
    return pd.DataFrame(rows)

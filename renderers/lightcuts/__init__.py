"""Foveated stochastic lightcuts (seed 003) and its stochastic-lightcuts core (Lin & Yuksel 2020).

Core on plain arrays: ``tree`` (perfect binary light tree), ``sampling`` (cuts, hierarchical importance
sampling, shading), ``fpsm`` (the foveated perceptual sensitivity map, seed 003 §3.1), ``multires``
(multi-resolution light-sample selection, §3.2), ``foveated`` (the per-frame pipeline), ``visibility``
(Embree shadow rays). On the scene model of ``renderers``: ``glossy`` (one-bounce glossy pass), ``plugin``
(renderers ``fsl``, ``sl`` with its presets ``sl_e``, ``sl_f``, ``sl_p``, ``sl_as``, ``sl_gt``), ``scenes``
(``cornell_many``, ``study``, ``yard``, ``sponza_vpl``) and ``tables`` (seed 003 Tables 1–4 as records).
See docs/lightcuts.md.
"""

__all__ = ["LightTree", "build_light_tree"]


def __getattr__(name):  # lazy (PEP 562): ``renderers.lightcuts.options`` is imported without numpy
    if name in __all__:
        from . import tree

        return getattr(tree, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")

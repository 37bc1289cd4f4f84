"""Foveated stochastic lightcuts (seed 003) and its stochastic-lightcuts core (Lin & Yuksel 2020).

Core on plain arrays: ``tree`` (perfect binary light tree), ``sampling`` (cuts, hierarchical importance
sampling, shading), ``fpsm`` (the foveated perceptual sensitivity map, seed 003 §3.1), ``multires``
(multi-resolution light-sample selection, §3.2), ``foveated`` (the per-frame pipeline), ``visibility``
(Embree shadow rays). On the scene model of ``renderers``: ``glossy`` (one-bounce glossy pass), ``plugin``
(renderers ``fsl``, ``sl`` with its presets ``sl_e``, ``sl_f``, ``sl_p``, ``sl_as``, ``sl_gt``), ``scenes``
(``cornell_many``, ``study``, ``yard``, ``sponza_vpl``) and ``tables`` (seed 003 Tables 1–4 as records).
See docs/lightcuts.md.
"""

from .tree import LightTree, build_light_tree

__all__ = ["LightTree", "build_light_tree"]

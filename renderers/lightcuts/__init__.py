"""Foveated stochastic lightcuts (seed 003) and its stochastic-lightcuts core (Lin & Yuksel 2020).

Modules: ``tree`` (perfect binary light tree), ``sampling`` (cuts, hierarchical importance sampling,
shading), ``fpsm`` (the foveated perceptual sensitivity map, seed 003 §3.1), ``multires`` (multi-resolution
light-sample selection, seed 003 §3.2), ``visibility`` (Embree shadow rays). See docs/lightcuts.md.
"""

from .tree import LightTree, build_light_tree

__all__ = ["LightTree", "build_light_tree"]

"""The constants of the per-pixel physics, written once for both backends (issue 29 item 1).

The CPU kernels import these names; :func:`renderers.gpu.codegen.constants_glsl` emits every upper-case
``int``/``float`` of this module as a GLSL ``const`` of the same name (``constants_gen.glsl``), which the generated
and the remaining hand-written shaders use. Change a value here and both backends change.
"""

from __future__ import annotations

import math

# -- integer codes of the material / texture / light tables (renderers/tracer.py packs them, both backends read)
TEX_NONE, TEX_CHECKER, TEX_BRICK, TEX_NOISE = 0, 1, 2, 3
KIND_DIFFUSE, KIND_GLOSSY, KIND_METALLIC = 0, 1, 2
LIGHT_POINT, LIGHT_EMITTER, LIGHT_DIRECTIONAL = 0, 1, 2

INV_PI = 1.0 / math.pi

# -- luminance: Rec. 709 / sRGB primaries (light culling, FXAA's luma, the FPSM's luminance feature)
LUMA_R, LUMA_G, LUMA_B = 0.2126, 0.7152, 0.0722

# -- foveated visual acuity of seed 003 Eq 2 (Stengel et al.'s fall-off): fb_f = clamp(A - B e, FLOOR, 1),
# e in radians (full acuity within 4.0 deg, the floor from 26.9 deg on)
ACUITY_INTERCEPT = 1.1715
ACUITY_SLOPE = 2.45
ACUITY_FLOOR = 0.02

# -- lightcuts sampling limits: the distance clamp of Lin & Yuksel's bound (fraction of the scene's light radius),
# the shadow-ray origin offset (fraction of the scene's half-diagonal) and how much of a shadow segment is tested
LC_CLAMP_FRACTION = 1e-3
LC_OFFSET_FRACTION = 1e-4
LC_SHADOW_EPS = 1e-3
LC_SHADOW_END = 1.0 - LC_SHADOW_EPS
#: The largest float32 below 1: the GPU's float32 uniforms are kept below it, as the CPU's float64 ones below 1 - 2^-53
LC_ONE_MINUS_F32 = 1.0 - 2.0 ** -24

# -- the LP buffer's filters (renderers/antialias.py lp_filter): rows continued around the angular seam on each side
# for FXAA and for LMFR's Gaussian, and that Gaussian's sigma and radius (pixels)
LP_PAD_FXAA = 16
LP_PAD_GAUSS = 1
LP_GAUSS_SIGMA = 1.0
LP_GAUSS_RADIUS = 1

"""The one home of the GPU shaders' resources: storage buffers (binding point, element type), images (unit,
format) and uniforms (GLSL type), one table per family of shaders.

The shaders' declarations are generated from these tables (``<family>_decl_gen.glsl``, :func:`decl_glsl`, through
:func:`renderers.gpu.context.generated_source`), and the host binds and sets by the same names
(:meth:`renderers.gpu.frame.Frame.run`: :func:`buffer_binding`, :func:`image_unit`, :func:`check_uniforms`), so a
binding point or a uniform's type is written once. A name is declared by one family only; a shader includes the
families it uses (``#include`` expands a file once, so shared helpers may include the same family). Storage
blocks count against the compute stage's limit (16 on llvmpipe) even when a shader does not use them, so buffers
are split into the families of the shaders that use them; unused images and uniforms cost nothing. The
lightcuts passes' light tree is an image whose texel layout (:data:`TREE_TEXELS`) gives both the shaders'
accessors (``lc_tree_gen.glsl``) and the host's packing (``renderers.gpu.lightcuts.tree_table``).
"""

from __future__ import annotations

from typing import NamedTuple


class Buffer(NamedTuple):
    """A std430 storage buffer ``name[]`` of ``type`` at ``binding``."""
    binding: int
    type: str
    access: str = ""   # "readonly", "writeonly" or "" (read and write)
    note: str = ""


class Image(NamedTuple):
    """A 2-D image at image unit ``unit`` (``uimage2D`` for an unsigned format), always ``restrict``."""
    unit: int
    format: str
    access: str = ""
    note: str = ""


class Uniform(NamedTuple):
    type: str           # GLSL type; an array as "float[33]"
    note: str = ""


#: family -> {name: Buffer | Image | Uniform}.
FAMILIES: dict[str, dict[str, Buffer | Image | Uniform]] = {
    # common.glsl: the dispatch's grid (renderers/gpu/context.py Device.dispatch) and what most passes share.
    "common": {
        "u_groups_x": Uniform("int", "workgroups per row of the dispatch grid"),
        "u_group_rows": Uniform("int", "rows of context.STRIPES stripes (gid())"),
        "u_stripes": Uniform("int"),
        "u_n": Uniform("int", "invocations of the dispatch"),
        "u_loop_probe": Uniform("int", "2: the loop-limit probe of cnt_end()"),
        "u_width": Uniform("int", "of the screen (or of the pass's G-buffer)"),
        "u_height": Uniform("int"),
        "u_origin": Uniform("vec3", "the camera's position"),
        "u_gaze": Uniform("vec2", "gaze point (pixels)"),
        "u_c_r": Uniform("float", "the display's tan of one pixel's eccentricity step (geometry.c_r)"),
        "u_s0": Uniform("int", "first sample (row) of a slice"),
        "u_s1": Uniform("int", "end of the slice"),
        "u_lp_w": Uniform("int", "the LP buffer's width"),
        "u_lp_h": Uniform("int", "and height"),
    },
    # common.glsl (#ifdef COUNTERS): the frame's counters (renderers/gpu/frame.py COUNTERS).
    "counters": {"counters": Buffer(5, "uint", note="frame.COUNTERS, summed per workgroup")},
    # scene.glsl: the uploaded scene (renderers/gpu/upload.py), TEX_WIDTH texels per row, floats as their bits.
    "scene": {
        "t_nodes": Image(0, "rgba32ui", "readonly", "2 per node (bvh.py)"),
        "t_tris": Image(1, "rgba32ui", "readonly", "v0|prim, e1|material, e2|0"),
        "t_mats": Image(2, "rgba32ui", "readonly", "4 per material: mat_f's 14 columns, texture kind"),
        "t_lights": Image(3, "rgba32ui", "readonly", "pos|kind, int.|cast, dir|0"),
        "u_ambient": Uniform("vec3"),
        "u_background": Uniform("vec3"),
        "u_light_cull": Uniform("float", "eps of the light culling (renderers/_shade.py)"),
        "u_offset": Uniform("float", "shadow-ray offset: 1e-5 scene scale"),
        "u_far": Uniform("float", "4 scene scale"),
    },
    # camera.glsl: upload.camera_uniforms.
    "camera": {
        "u_cam_f": Uniform("dvec3", "forward"),
        "u_cam_r": Uniform("dvec3", "right"),
        "u_cam_u": Uniform("dvec3", "up"),
        "u_tan": Uniform("double", "tan(fov / 2)"),
        "u_screen": Uniform("vec2", "W, H"),
    },
    # samples.glsl: a batch of samples (frame.py sample_buffers); the output slot k of a sample is 3 floats of
    # outbuf or (OUT_IMAGE) texel (k mod u_out_w, k / u_out_w) of out_img, the LP buffer.
    "samples": {
        "samples": Buffer(6, "vec4", note="direction | output slot (int bits)"),
        "hits": Buffer(7, "vec2", note="triangle (int bits; -1: miss) | t"),
        "masks": Buffer(8, "uint", note="MASK_WORDS per sample: lights to test"),
        "partial": Buffer(9, "vec4", note="radiance without the shadowed lights"),
        "outbuf": Buffer(10, "float", note="3 floats per output slot"),
        "out_img": Image(4, "rgba32f", "writeonly"),
        "u_out_w": Uniform("int"),
        "u_count_at": Uniform("int", "counter holding the batch size, or -1: u_n"),
    },
    # samples.comp: the G-buffer of the deferred pipeline and GT's pixels.
    "passes": {
        "img": Buffer(15, "float", "writeonly", "RESOLVE: 3 floats per pixel"),
        "gbuf": Buffer(15, "vec2", note="triangle (int bits; -1: miss) | t"),
        "u_y0": Uniform("int", "first row of the batch"),
        "u_slot_base": Uniform("int", "output slot of its first sample"),
        "u_tent": Uniform("int", "1: tent filter (resolve_pixel)"),
    },
    # lp_cols.glsl: the LP layout (pipelines.py LPTables). Column c of t_cols: r(c + 0.5), L[c] / 2 pi, n[c],
    # L[c]; t_offs: two doubles per LP pixel (VaFR its offset from the gaze, LMFR/LaFR its row's (cos, sin)),
    # times col_scale[c] (1, or r(c + 0.5)).
    "lp": {
        "t_cols": Image(7, "rgba32f", "readonly", "TEX_WIDTH columns per row"),
        "t_offs": Image(6, "rgba32ui", "readonly", "two doubles per LP pixel"),
        "col_scale": Buffer(12, "double", "readonly"),
        "u_w_eff": Uniform("int", "columns the inverse mapping reads"),
        "u_gaze_d": Uniform("dvec2", "u_gaze in double"),
    },
    # lp_map.glsl: the forward mapping's parameter vector P and (VaFR, USE_TABLE) the u(r) table.
    "lp_map": {
        "FP": Buffer(11, "float", "readonly", "mapping._params_vector()"),
        "utab": Buffer(13, "vec2", "readonly", "u(k / step), exact-kernel flag"),
        "u_inv_step": Uniform("float"),
        "u_kmax": Uniform("int"),
    },
    # The LP pixels' flags: bit 0 shaded (in the left eye: needed), bit 2 read by a border pixel's bilinear fetch.
    "flags": {"flags": Buffer(14, "uint")},
    # lp_flags.comp: the CPU's list of border-footprint pixels.
    "marks": {"marks": Buffer(13, "int", "readonly")},
    # The LP filters and the screen passes (pipelines.py finish_lp): the LP buffer in and out (lp_pad.glsl), the
    # filters' weights and FXAA's luma.
    "filters": {
        "src": Image(4, "rgba32f", "readonly"),
        "dst": Image(5, "rgba32f", "writeonly"),
        "lp": Image(4, "rgba32f", note="fill_rows.comp: the LP buffer, filled in place"),
        "luma": Image(6, "r32f", note="lp_luma.comp writes it, fxaa.comp reads it"),
        "u_w": Uniform("float[33]", "Gaussian weights: antialias.FOVEAL_WEIGHTS (foveal.comp), _gauss1d (gauss3)"),
        "u_edges": Uniform("float[3]", "antialias.FOVEAL_BANDS_DEG"),
        "u_radii": Uniform("int[4]", "antialias.FOVEAL_RADII"),
        "u_subpix": Uniform("double"),
        "u_edge_threshold": Uniform("double"),
        "u_edge_threshold_min": Uniform("double"),
        "u_exposure": Uniform("float"),
    },
    # screen_out.glsl: a screen pass's output, an image (OUT_IMAGE) or 3 floats per pixel, row-major.
    "screen": {
        "dst_img": Image(5, "rgba32f", "writeonly"),
        "dst_buf": Buffer(15, "float", "writeonly", "an (H, W, 3) float32 array as is"),
    },
    # rep.glsl: reprojection (pipelines.py reproject). Depths are float bits (positive floats order like their
    # bits, so atomicMin is a depth test). Of the writers whose depth is the minimum at a pixel, the one with the
    # largest id + 1 writes its colour (winner; 0: none yet): racing threads would leave a different colour from
    # run to run (a fronto-parallel wall gives many equal float depths). A pixel's writers are all splats or all
    # triangles (rep_splat.comp).
    "rep": {
        "warp": Buffer(0, "vec4", note="u, phi, z (INF: miss or behind), target"),
        "zbuf": Buffer(1, "uint", note="splats' depth"),
        "covered": Buffer(2, "uint"),
        "ztri": Buffer(3, "uint", note="nearest warped triangle"),
        "winner": Buffer(15, "uint"),
        "left_lp": Image(5, "rgba32f", "readonly"),
        "right_lp": Image(4, "rgba32f", "writeonly"),
        "u_splat_margin": Uniform("float"),
        "u_max_ratio": Uniform("float"),
        "u_max_extent": Uniform("float"),
        "u_left_pos": Uniform("vec3"),
        "u_right_pos": Uniform("vec3"),
    },
    # fpsm.comp (renderers/gpu/fpsm.py).
    "fpsm": {
        "fp_px": Buffer(14, "vec4", note="luminance of fb' upsampled | fb_st | fb_l | rho"),
        "fp_low": Buffer(15, "float", note="bicubic coefficients | pyramid levels 1, 2"),
        "u_coef": Uniform("ivec2", "size of the coefficients (fb' padded)"),
        "u_g1": Uniform("ivec2", "pyramid level 1's size in fp_low"),
        "u_g2": Uniform("ivec2", "level 2's"),
        "u_g1_at": Uniform("int", "level 1's offset (the coefficients' is 0)"),
        "u_g2_at": Uniform("int"),
        "u_scale": Uniform("vec2", "(w' / w, h' / h)"),
        "u_range": Uniform("vec2", "fb''s luminance range, clipped at 0"),
        "u_eps": Uniform("float"),
        "u_alpha": Uniform("float"),
        "u_moving": Uniform("int"),
        "u_max_lspp": Uniform("int"),
        "u_max_rspp": Uniform("int"),
        "u_vp": Uniform("mat4", "world -> clip of this frame's camera"),
        "u_vp_prev": Uniform("mat4", "and of the previous one"),
    },
    # The storage buffers of the lightcuts passes (renderers/gpu/lightcuts.py). Pixel p of a G-buffer is entry p; a
    # tile's sample lists are at (p - u_first) * CUT_MAX + s. LcSample: SAMPLE_FIELDS.
    "lc_buffers": {
        "g_pos": Buffer(0, "vec4", note="hit position | valid (1 or 0)"),
        "g_nrm": Buffer(1, "vec4", note="unit normal facing the viewer | glossy (1 or 0)"),
        "g_alb": Buffer(2, "vec4", note="diffuse albedo (0 when metallic) | exponent"),
        "g_ks": Buffer(3, "vec4", note="specular colour (0 unless glossy/metallic) | 0"),
        "g_base": Buffer(4, "vec4", note="emission + ambient; the background on a miss"),
        "bounds": Buffer(6, "uint", note="G-buffer points' box: min xyz, max xyz (ordered bits)"),
        "ctl": Buffer(7, "ivec4", note="cut budget #L | glossy rays | FPSM map (bits) | 0"),
        "smp": Buffer(8, "LcSample", note="a tile's samples: cut node, light (leaf node, -1: none), pdf"),
        "pix": Buffer(9, "ivec4", note="cut size | light samples | reused | LS' count"),
        "lr_ls": Buffer(10, "LcSample", note="LS': each low-resolution pixel's samples sorted by leaf, with depth"),
        "lr_pix": Buffer(11, "ivec4", note="the low-resolution G-buffer's pix"),
        "rad": Buffer(12, "vec4", note="direct diffuse radiance"),
        "gloss": Buffer(13, "vec4", note="glossy radiance"),
    },
    # The light tree (renderers/gpu/lightcuts.py DeviceTree; its texels: TREE_TEXELS).
    "lc_tree": {
        "t_tree": Image(4, "rgba32ui", "readonly", "6 N texels for N leaves (TREE_TEXELS)"),
        "u_n_leaves": Uniform("int", "N"),
        "u_levels": Uniform("int", "log2 N + 1 (the n of seed 003 Eq 9)"),
        "u_clamp2": Uniform("float", "(0.001 scene light radius)^2 (sampling.clamp2)"),
        "u_one_sided": Uniform("int", "the tree has emitter normals"),
    },
    # The lightcuts passes' uniforms (renderers/gpu/lightcuts.py).
    "lightcuts": {
        "u_first": Uniform("int", "first pixel of the tile"),
        "u_seed": Uniform("uvec2", "random stream (64 bits: lo, hi)"),
        "u_id_base": Uniform("uint", "pixel ids of this pass start here (low-resolution pass: after the frame's)"),
        "u_budget": Uniform("int", "lc_cut.comp: the cut size of every pixel, or -1: each pixel's ctl.x"),
        "u_lr_scale": Uniform("dvec2", "lc_select.comp: (w' / w, h' / h)"),
        "u_lr_width": Uniform("int", "size of the low-resolution image"),
        "u_lr_height": Uniform("int"),
        "u_step": Uniform("dvec2", "lc_gbuffer.comp: screen step between rays"),
        "u_full": Uniform("int", "the frame's G-buffer (counts, bounds)"),
        "u_shadows": Uniform("int"),
        "u_accumulate": Uniform("int", "lc_shade.comp: add to rad (sl_gt's passes)"),
        "u_rspp": Uniform("int", "lc_glossy.comp: rays per glossy pixel, or -1: ctl.y"),
        "u_r0": Uniform("int", "first ray slot of the dispatch"),
        "u_r1": Uniform("int"),
        "u_bounce_seed": Uniform("uvec2"),
        "u_bounce_lspp": Uniform("int"),
        "u_glossy_offset": Uniform("float"),
    },
}


def _entries(kind) -> dict:
    out = {}
    for family, table in FAMILIES.items():
        for name, e in table.items():
            if name in out:
                raise ValueError(f"GPU resource {name!r} is declared by two families (renderers/gpu/bindings.py)")
            if isinstance(e, kind):
                out[name] = e
    return out


BUFFERS: dict[str, Buffer] = _entries(Buffer)
IMAGES: dict[str, Image] = _entries(Image)
UNIFORMS: dict[str, Uniform] = _entries(Uniform)


def decl_glsl(family: str) -> str:
    """The GLSL declarations of ``family`` (``<family>_decl_gen.glsl``)."""
    out = [f"// Generated from renderers/gpu/bindings.py (FAMILIES[{family!r}]) by renderers/gpu/bindings.py: "
           "do not edit."]
    for name, e in FAMILIES[family].items():
        note = f"  // {e.note}" if e.note else ""
        if isinstance(e, Buffer):
            access = f"{e.access} " if e.access else ""
            out.append(f"layout(std430, binding = {e.binding}) {access}buffer B_{name} {{ {e.type} {name}[]; }};{note}")
        elif isinstance(e, Image):
            kind = "uimage2D" if e.format.endswith("ui") else "image2D"
            access = f" {e.access}" if e.access else ""
            out.append(f"layout(binding = {e.unit}, {e.format}) uniform restrict{access} {kind} {name};{note}")
        else:
            base, _, size = e.type.partition("[")
            out.append(f"uniform {base} {name}{'[' + size if size else ''};{note}")
    return "\n".join(out) + "\n"


#: The fields of a lightcuts light sample (``LcSample``, 16 bytes; buffers ``smp``, ``lr_ls``).
SAMPLE_FIELDS = (("int", "node"), ("int", "leaf"), ("float", "pdf"), ("int", "depth"))
#: The light tree's texels (image ``t_tree``), read by the shaders' accessors (:func:`tree_glsl`) and packed by
#: ``renderers.gpu.lightcuts.tree_table``: accessor -> (first texel / N, texels per entry, texel in the entry,
#: components). Node k (1 <= k < 2N): (bmin, intensity), (bmax, 0); leaf j (0 <= j < N): (RGB intensity, 0),
#: (emitter normal, 0); a leaf's light sits at its node's box (``light_pos(j)``: bmin = bmax of node N + j).
TREE_TEXELS = {"node_min": (0, 2, 0, "xyz"), "node_inten": (0, 2, 0, "w"), "node_max": (0, 2, 1, "xyz"),
               "light_pos": (2, 2, 0, "xyz"), "light_rgb": (4, 2, 0, "xyz"), "light_nrm": (4, 2, 1, "xyz")}
#: The tree's uniforms, in the order ``DeviceTree`` gives their values.
TREE_UNIFORMS = tuple(k for k, e in FAMILIES["lc_tree"].items() if isinstance(e, Uniform))


def lc_buffers_glsl() -> str:
    """The lightcuts passes' sample struct and buffers (``lc_buffers_gen.glsl``)."""
    fields = " ".join(f"{t} {n};" for t, n in SAMPLE_FIELDS)
    return f"struct LcSample {{ {fields} }};\n" + decl_glsl("lc_buffers")


def tree_glsl() -> str:
    """The light tree's image, uniforms and the accessors of :data:`TREE_TEXELS` (``lc_tree_gen.glsl``)."""
    out = [decl_glsl("lc_tree").rstrip("\n")]
    for name, (first, step, texel, comps) in TREE_TEXELS.items():
        index = "".join([f"{first} * u_n_leaves + " if first else "", f"{step} * k", f" + {texel}" if texel else ""])
        out.append(f"{'float' if len(comps) == 1 else f'vec{len(comps)}'} {name}(int k) "
                   f"{{ return fetchf(t_tree, {index}).{comps}; }}")
    return "\n".join(out) + "\n"


def buffer_binding(name: str) -> int:
    """The binding point of storage buffer ``name``; an unknown name is refused, naming it."""
    if name in BUFFERS:
        return BUFFERS[name].binding
    raise KeyError(f"no GPU storage buffer is named {name!r} (renderers/gpu/bindings.py FAMILIES)")


def image_unit(name: str) -> int:
    """The image unit of image ``name``; an unknown name is refused, naming it."""
    if name in IMAGES:
        return IMAGES[name].unit
    raise KeyError(f"no GPU image is named {name!r} (renderers/gpu/bindings.py FAMILIES)")


def check_uniforms(values: dict) -> None:
    """Refuse a uniform that no table declares, naming it (a misspelt name would otherwise be skipped as one the
    shader does not use)."""
    unknown = [k for k in values if k not in UNIFORMS]
    if unknown:
        raise KeyError(f"no GPU uniform is named {', '.join(map(repr, unknown))} (renderers/gpu/bindings.py "
                       f"FAMILIES)")

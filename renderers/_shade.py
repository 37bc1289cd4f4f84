"""Compiled shading kernels (numba): procedural textures and direct lighting with light culling.

Shading model at a surface point ``p`` with normal ``n`` (facing the viewer), view direction ``w_o`` and
textured albedo ``a`` (see :class:`renderers.scene.Material`), for a light with incident direction ``w_i`` and
irradiance ``E`` at ``p`` (point light ``E = I max(0, n.w_i) / d^2``; emissive triangle additionally
``* max(0, -n_l.w_i)``; directional ``E = E_0 max(0, n.w_i)``):

    L_o = L_e + ambient * a + sum_lights V(p, light) * f(w_i, w_o) * E

    f = (1 - metallic) * a / pi  +  k_s * (s + 8) / (8 pi) * max(0, n.h)^s,      h = normalize(w_i + w_o)

with ``s = 2 / roughness^2 - 2`` (Blinn-Phong with the usual energy normalisation), ``k_s = specular`` (white)
for glossy and ``k_s = a`` for metallic materials; diffuse materials skip the lobe. ``V`` is the visibility
from a shadow ray.

Light culling (documented bound): per point, the unshadowed contributions ``c_k`` (luminance) are sorted and the
smallest lights are dropped while their running sum stays ``<= eps * sum_k c_k``. Shadowing only lowers each
term, so the dropped radiance is at most ``eps`` times the point's unshadowed direct-light estimate
(``eps = light_cull``); with ``eps = 0`` no light is culled.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from .constants import (INV_PI, KIND_DIFFUSE, KIND_GLOSSY, KIND_METALLIC, LIGHT_DIRECTIONAL, LIGHT_EMITTER,  # noqa: F401
                        LIGHT_POINT, LUMA_B, LUMA_G, LUMA_R, TEX_BRICK, TEX_CHECKER, TEX_NONE, TEX_NOISE)

#: The scalar kernels that renderers/gpu/codegen.py translates into GLSL (``shade_gen.glsl``): the texture
#: closure in double precision (as on the CPU: lattice lines fall on the same side), the lobes in float.
GLSL_DOUBLE_ROOTS = ("texture_weight",)
GLSL_FLOAT_ROOTS = ("material_lobes", "light_direction", "irradiance_factor", "specular_lobe", "luminance",
                    "facing_normal")
#: The kernels that read the scene's tables (``L_*``, ``mat_f``, ``mat_i`` bound to the GPU's light and material
#: images) and write a hit's record (``P``, ``Ng``, ``albedo``, ``base``, ``ks``, ``exponent`` bound to the shader's
#: ``hit_surf``): ``lights_gen.glsl``.
GLSL_LIGHT_ROOTS = ("hit_material", "hit_surface", "light_term", "shadow_direction")
#: The light loop of a shading point (``contrib``, ``lum`` bound to samples.comp's per-point arrays):
#: ``light_loop_gen.glsl``.
GLSL_POINT_ROOTS = ("light_loop",)


@njit(cache=True, inline="always")
def _hash3(x, y, z):
    h = (x * 73856093) ^ (y * 19349663) ^ (z * 83492791)
    h = (h ^ (h >> 13)) * 1274126177
    h = h ^ (h >> 16)
    return (h & 0xFFFF) / 65535.0


@njit(cache=True, inline="always")
def _smooth(t):
    return t * t * (3.0 - 2.0 * t)


@njit(cache=True)
def value_noise(x, y, z):
    """Trilinear value noise on the integer lattice with smoothstep weights, in [0, 1]."""
    xi, yi, zi = math.floor(x), math.floor(y), math.floor(z)
    fx, fy, fz = _smooth(x - xi), _smooth(y - yi), _smooth(z - zi)
    X, Y, Z = np.int64(xi), np.int64(yi), np.int64(zi)
    acc = 0.0
    for dz in range(2):
        wz = fz if dz else 1.0 - fz
        for dy in range(2):
            wy = fy if dy else 1.0 - fy
            for dx in range(2):
                wx = fx if dx else 1.0 - fx
                acc += wx * wy * wz * _hash3(X + dx, Y + dy, Z + dz)
    return acc


@njit(cache=True)
def texture_weight(kind, scale, px, py, pz, nx, ny, nz):
    """Weight of ``albedo`` (1) versus ``albedo2`` (0) of a procedural texture at ``p`` (normal ``n``)."""
    if kind == TEX_NONE:
        return 1.0
    ax, ay, az = abs(nx), abs(ny), abs(nz)
    if ax >= ay and ax >= az:
        s, t = pz / scale, py / scale
    elif ay >= az:
        s, t = px / scale, pz / scale
    else:
        s, t = px / scale, py / scale
    if kind == TEX_CHECKER:
        return 1.0 if (math.floor(s) + math.floor(t)) % 2 == 0 else 0.0
    if kind == TEX_BRICK:
        tt = 2.0 * t
        row = math.floor(tt)
        ss = s + 0.5 * (row % 2)
        fs = ss - math.floor(ss)
        ft = tt - row
        return 0.0 if (fs < 0.05 or ft < 0.1) else 1.0
    # noise: two octaves
    q = 1.0 / scale
    n = 0.65 * value_noise(px * q, py * q, pz * q) + 0.35 * value_noise(2.03 * px * q, 2.03 * py * q,
                                                                       2.03 * pz * q)
    return min(1.0, max(0.0, 1.6 * (n - 0.5) + 0.5))


@njit(cache=True, inline="always")
def material_lobes(metallic_flag, glossy_flag, s_exp):
    """``(k_d, glossy, metallic, norm)`` of a material: the Lambert weight ``1/pi`` (0 for metallic), whether the
    Blinn-Phong lobe is evaluated and whether it is tinted by the albedo (1.0 or 0.0), and the lobe's energy
    normalisation ``(s + 8) / (8 pi)`` (module docstring)."""
    metallic = 1.0 if metallic_flag > 0.5 else 0.0
    glossy = 1.0 if (glossy_flag > 0.5 or metallic_flag > 0.5) else 0.0
    kd = 0.0 if metallic_flag > 0.5 else INV_PI
    return kd, glossy, metallic, (s_exp + 8.0) / (8.0 * math.pi)


@njit(cache=True, inline="always")
def light_direction(kind, lx, ly, lz, dx, dy, dz, px, py, pz):
    """Unit direction ``w_i`` from ``p`` to a light at ``l`` (directional: ``-d``) and ``1 / d^2`` (1)."""
    if kind == LIGHT_DIRECTIONAL:
        return -dx, -dy, -dz, 1.0
    wx, wy, wz = lx - px, ly - py, lz - pz
    d2 = wx * wx + wy * wy + wz * wz
    inv_d = 1.0 / math.sqrt(d2)
    return wx * inv_d, wy * inv_d, wz * inv_d, inv_d * inv_d


@njit(cache=True, inline="always")
def irradiance_factor(kind, dx, dy, dz, nx, ny, nz, wx, wy, wz, inv_d2):
    """``E / I = max(0, n.w_i) / d^2``, times ``max(0, -n_l.w_i)`` for an emitter (normal ``d``); 0 when the
    light is behind the point or below its horizon."""
    cos_t = nx * wx + ny * wy + nz * wz
    e = cos_t * inv_d2
    if kind == LIGHT_EMITTER:
        e *= max(0.0, -(dx * wx + dy * wy + dz * wz))
    if cos_t <= 0.0 or e <= 0.0:
        return 0.0
    return e


@njit(cache=True, inline="always")
def specular_lobe(norm, s_exp, nx, ny, nz, wx, wy, wz, vx, vy, vz):
    """Normalised Blinn-Phong ``norm * max(0, n.h)^s``, ``h = normalize(w_i + w_o)`` (0 when ``h`` vanishes)."""
    hx, hy, hz = wx + vx, wy + vy, wz + vz
    hl = math.sqrt(hx * hx + hy * hy + hz * hz)
    if hl > 0.0:
        nh = (nx * hx + ny * hy + nz * hz) / hl
        if nh > 0.0:
            return norm * nh ** s_exp
    return 0.0


@njit(cache=True, inline="always")
def luminance(r, g, b):
    """Luminance of linear Rec. 709 RGB."""
    return LUMA_R * r + LUMA_G * g + LUMA_B * b


@njit(cache=True, inline="always")
def hit_material(i, m, w, mat_f, ambient, albedo, base, ks):
    """Material terms of hit ``i`` on material ``m`` (texture weight ``w``) for the G-buffer: ``albedo[i]`` the
    textured albedo (0 for metallic: no Lambert lobe), ``base[i]`` emission + ambient albedo, ``ks[i]`` the specular
    colour (the albedo for metallic, ``specular`` for glossy, 0 for diffuse); returns whether the Blinn-Phong lobe
    is evaluated (glossy or metallic)."""
    metallic = mat_f[m, 12] > 0.5
    gl = mat_f[m, 13] > 0.5 or metallic
    for c in range(3):
        a = w * mat_f[m, c] + (1.0 - w) * mat_f[m, 3 + c]
        albedo[i, c] = 0.0 if metallic else a
        base[i, c] = mat_f[m, 6 + c] + (0.0 if metallic else ambient[c] * a)
        ks[i, c] = (a if metallic else mat_f[m, 11]) if gl else 0.0
    return gl


@njit(cache=True, inline="always")
def hit_surface(i, m, P, Ng, mat_f, mat_i, ambient, albedo, base, ks, exponent):
    """The G-buffer's material record of hit ``i`` at ``P[i]`` (normal ``Ng[i]``) on material ``m``: the texture
    weight, :func:`hit_material`'s terms and the Blinn-Phong ``exponent[i]``; returns the lobe flag."""
    w = texture_weight(mat_i[m, 0], mat_f[m, 9], P[i, 0], P[i, 1], P[i, 2], Ng[i, 0], Ng[i, 1], Ng[i, 2])
    exponent[i] = mat_f[m, 10]
    return hit_material(i, m, w, mat_f, ambient, albedo, base, ks)


@njit(cache=True, inline="always")
def facing_normal(e1x, e1y, e1z, e2x, e2y, e2z, dx, dy, dz):
    """Unit geometric normal ``e1 x e2`` of a triangle with edges ``e1, e2``, turned to face a ray along ``d``."""
    nx = e1y * e2z - e1z * e2y
    ny = e1z * e2x - e1x * e2z
    nz = e1x * e2y - e1y * e2x
    ln = math.sqrt(nx * nx + ny * ny + nz * nz)
    if ln > 0.0:
        nx, ny, nz = nx / ln, ny / ln, nz / ln
    if nx * dx + ny * dy + nz * dz > 0.0:
        return -nx, -ny, -nz
    return nx, ny, nz


@njit(cache=True, inline="always")
def light_term(j, L_kind, L_pos, L_dir, L_int, px, py, pz, nx, ny, nz, vx, vy, vz, kd, ar, ag, ab, glossy, ksr, ksg,
               ksb, norm, s_exp):
    """Unshadowed contribution ``(r, g, b, lobe)`` of light ``j`` at ``p`` (normal ``n``, view ``v``): ``f E`` of
    the module docstring for the material's Lambert weight ``kd``, albedo ``a``, lobe flag ``glossy`` (1.0 or 0.0),
    specular colour ``ks``, normalisation ``norm`` and exponent ``s``; ``lobe`` is 1.0 when the Blinn-Phong lobe was
    evaluated (the glossy_evaluations counter). All zero when the light is behind the point or below its horizon."""
    wx, wy, wz, inv_d2 = light_direction(L_kind[j], L_pos[j, 0], L_pos[j, 1], L_pos[j, 2], L_dir[j, 0], L_dir[j, 1],
                                         L_dir[j, 2], px, py, pz)
    e = irradiance_factor(L_kind[j], L_dir[j, 0], L_dir[j, 1], L_dir[j, 2], nx, ny, nz, wx, wy, wz, inv_d2)
    if e == 0.0:
        return 0.0, 0.0, 0.0, 0.0
    fr, fg, fb = kd * ar, kd * ag, kd * ab
    lobe = 0.0
    if glossy > 0.5:
        sp = specular_lobe(norm, s_exp, nx, ny, nz, wx, wy, wz, vx, vy, vz)
        fr += ksr * sp
        fg += ksg * sp
        fb += ksb * sp
        lobe = 1.0
    return fr * e * L_int[j, 0], fg * e * L_int[j, 1], fb * e * L_int[j, 2], lobe


@njit(cache=True, inline="always")
def light_loop(i, k, L_kind, L_pos, L_dir, L_int, px, py, pz, nx, ny, nz, vx, vy, vz, kd, ar, ag, ab, glossy, ksr,
               ksg, ksb, norm, s_exp, contrib, lum):
    """Unshadowed contributions ``contrib[i, j]`` (:func:`light_term`) of the ``k`` lights at point ``i`` and their
    luminances ``lum[j]``; returns the total luminance and the number of lobe evaluations."""
    total = 0.0
    n_gloss = 0
    for j in range(k):
        cr, cg, cb, g = light_term(j, L_kind, L_pos, L_dir, L_int, px, py, pz, nx, ny, nz, vx, vy, vz, kd, ar, ag,
                                   ab, glossy, ksr, ksg, ksb, norm, s_exp)
        contrib[i, j, 0] = cr
        contrib[i, j, 1] = cg
        contrib[i, j, 2] = cb
        if g > 0.5:
            n_gloss += 1
        lum[j] = luminance(cr, cg, cb)
        total += lum[j]
    return total, n_gloss


@njit(cache=True, inline="always")
def shadow_direction(j, L_kind, L_pos, L_dir, ox, oy, oz, offset, far):
    """Unit direction from a shadow ray's origin ``o`` towards light ``j`` and the ray's length: ``far`` for a
    directional light, else the distance less ``offset`` at each end (never negative)."""
    if L_kind[j] == LIGHT_DIRECTIONAL:
        return -L_dir[j, 0], -L_dir[j, 1], -L_dir[j, 2], far
    dx, dy, dz = L_pos[j, 0] - ox, L_pos[j, 1] - oy, L_pos[j, 2] - oz
    d = math.sqrt(dx * dx + dy * dy + dz * dz)
    return dx / d, dy / d, dz / d, max(d - 2.0 * offset, 0.0)


@njit(cache=True, parallel=True)
def shade_contributions(P, N, V, mid, mat_f, mat_i, L_pos, L_int, L_dir, L_kind, ambient, eps,
                        contrib, base, need, counts):
    """Unshadowed light contributions and the culling decision for each point.

    P, N, V : (n, 3) float64 positions, unit normals facing the viewer, unit directions to the viewer.
    mid : (n,) int32 material ids.
    mat_f : (m, 14) float64 per material: albedo(3) albedo2(3) emission(3) tex_scale exponent specular
        metallic glossy.  mat_i : (m, 2) int64: texture kind, material kind.
    L_pos, L_int, L_dir : (k, 3) light positions, intensities (irradiance for directional), emitter normals or
        directional light directions.  L_kind : (k,) int64.
    contrib : (n, k, 3) float32 out. base : (n, 3) float32 out (emission + ambient albedo).
    need : (n, k) bool out: the light's contribution is > 0 and not culled.
    counts : (n, 2) int64 out: glossy evaluations, culled lights.
    """
    n = P.shape[0]
    k = L_pos.shape[0]
    for i in prange(n):
        px, py, pz = P[i, 0], P[i, 1], P[i, 2]
        nx, ny, nz = N[i, 0], N[i, 1], N[i, 2]
        vx, vy, vz = V[i, 0], V[i, 1], V[i, 2]
        m = mid[i]
        w = texture_weight(mat_i[m, 0], mat_f[m, 9], px, py, pz, nx, ny, nz)
        ar = w * mat_f[m, 0] + (1.0 - w) * mat_f[m, 3]
        ag = w * mat_f[m, 1] + (1.0 - w) * mat_f[m, 4]
        ab = w * mat_f[m, 2] + (1.0 - w) * mat_f[m, 5]
        s_exp = mat_f[m, 10]
        kd, glossy_w, metal_w, norm = material_lobes(mat_f[m, 12], mat_f[m, 13], s_exp)
        metallic = metal_w > 0.5
        if metallic:
            ksr, ksg, ksb = ar, ag, ab
        else:
            ksr = ksg = ksb = mat_f[m, 11]
        base[i, 0] = mat_f[m, 6] + ambient[0] * ar * (1.0 - metal_w)
        base[i, 1] = mat_f[m, 7] + ambient[1] * ag * (1.0 - metal_w)
        base[i, 2] = mat_f[m, 8] + ambient[2] * ab * (1.0 - metal_w)
        lum = np.empty(k)
        total, n_gloss = light_loop(i, k, L_kind, L_pos, L_dir, L_int, px, py, pz, nx, ny, nz, vx, vy, vz, kd, ar,
                                    ag, ab, glossy_w, ksr, ksg, ksb, norm, s_exp, contrib, lum)
        culled = 0
        for j in range(k):
            need[i, j] = lum[j] > 0.0
        if eps > 0.0 and total > 0.0:
            order = np.argsort(lum)
            budget = eps * total
            acc = 0.0
            for q in range(k):
                j = order[q]
                if lum[j] <= 0.0:
                    continue
                if acc + lum[j] > budget:
                    break
                acc += lum[j]
                need[i, j] = False
                contrib[i, j, 0] = contrib[i, j, 1] = contrib[i, j, 2] = 0.0
                culled += 1
        counts[i, 0] = n_gloss
        counts[i, 1] = culled


@njit(cache=True)
def shadow_rays(P, N, need, cast, L_pos, L_dir, L_kind, offset, far, orig, dirs, dists, pairs):
    """Fill shadow rays for every needed (point, light) pair whose light casts shadows; returns their count.

    Origins are offset by ``offset`` along the normal; the ray stops ``offset`` short of the light.
    ``pairs[r] = i * k + j`` records which pair ray ``r`` tests.
    """
    n, k = need.shape
    r = 0
    for i in range(n):
        ox = P[i, 0] + offset * N[i, 0]
        oy = P[i, 1] + offset * N[i, 1]
        oz = P[i, 2] + offset * N[i, 2]
        for j in range(k):
            if not need[i, j] or not cast[j]:
                continue
            dx, dy, dz, d = shadow_direction(j, L_kind, L_pos, L_dir, ox, oy, oz, offset, far)
            orig[r, 0], orig[r, 1], orig[r, 2] = ox, oy, oz
            dirs[r, 0], dirs[r, 1], dirs[r, 2] = dx, dy, dz
            dists[r] = d
            pairs[r] = i * k + j
            r += 1
    return r


@njit(cache=True, parallel=True)
def accumulate(contrib, need, base, out):
    """``out = base + sum_j contrib[:, j]`` over the lights still needed (visible)."""
    n, k = need.shape
    for i in prange(n):
        r, g, b = base[i, 0], base[i, 1], base[i, 2]
        for j in range(k):
            if need[i, j]:
                r += contrib[i, j, 0]
                g += contrib[i, j, 1]
                b += contrib[i, j, 2]
        out[i, 0], out[i, 1], out[i, 2] = r, g, b


@njit(cache=True)
def clear_occluded(need, pairs, hit):
    """Mark the pairs whose shadow ray hit something as not visible."""
    k = need.shape[1]
    for r in range(pairs.shape[0]):
        if hit[r] != -1:
            p = pairs[r]
            need[p // k, p % k] = False


@njit(cache=True, parallel=True)
def hit_geometry(origin, d, t, prim, vertices, faces, P, N, V):
    """Hit points ``P = o + t d``, unit geometric normals facing the ray ``N`` and view directions ``V = -d``."""
    for i in prange(d.shape[0]):
        f = prim[i]
        a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
        e1x = vertices[b, 0] - vertices[a, 0]
        e1y = vertices[b, 1] - vertices[a, 1]
        e1z = vertices[b, 2] - vertices[a, 2]
        e2x = vertices[c, 0] - vertices[a, 0]
        e2y = vertices[c, 1] - vertices[a, 1]
        e2z = vertices[c, 2] - vertices[a, 2]
        dx, dy, dz = d[i, 0], d[i, 1], d[i, 2]
        nx, ny, nz = facing_normal(e1x, e1y, e1z, e2x, e2y, e2z, dx, dy, dz)
        ti = t[i]
        P[i, 0] = origin[0] + dx * ti
        P[i, 1] = origin[1] + dy * ti
        P[i, 2] = origin[2] + dz * ti
        N[i, 0], N[i, 1], N[i, 2] = nx, ny, nz
        V[i, 0], V[i, 1], V[i, 2] = -dx, -dy, -dz

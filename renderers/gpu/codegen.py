"""GLSL generated from the CPU code, so that the GPU evaluates the same formulas without a second copy
(issue 29: one source for the per-pixel physics; docs/gpu.md lists what is generated and what is not).

* :func:`foveation_glsl` translates the scalar kernels of :mod:`renderers.foveation._kernels` (the forward and
  inverse mappings of VaFR, LMFR and LaFR; seed 001 Eq 1, 3-12, 14-15) into functions prefixed ``fov_``. The
  parameter vector ``P`` becomes the storage buffer ``FP[]`` (the CPU's ``FoveationMapping._params_vector()``,
  uploaded as float32).
* :func:`shade_glsl` translates the shading kernels of :mod:`renderers._shade` (textures and value noise in
  double precision, BRDF lobes and light terms in float32), prefixed ``shade_``.
* :func:`lights_glsl` translates the per-light kernels of :mod:`renderers._shade` (a light's contribution, a
  shadow ray's direction), the light table bound to the shader's light image.
* :func:`lightcuts_glsl` translates the random numbers (double) and the bounds, cut error, branch probability,
  descent, Lambertian estimate and the per-pixel bodies of the sampling passes (float32) of
  :mod:`renderers.lightcuts._kernels` and :mod:`~renderers.lightcuts.multires`, prefixed ``lc_``; the tree's arrays
  are bound to the shader's tree image, the pixel arrays to its storage buffers (``Translator.bindings``);
  :func:`lightcuts_bounce_glsl` the same pixel kernels bound to one glossy ray's hit (``lc_glossy.comp``).
* :func:`glossy_glsl` translates the glossy pass's per-ray lobe sampling of :mod:`renderers.lightcuts.glossy`,
  prefixed ``glossy_`` (its frame and uniforms are ``lightcuts_gen.glsl``'s: ``Translator.externals``).
* :func:`fpsm_glsl` translates the per-pixel kernels of :mod:`renderers.lightcuts.fpsm` (seed 003 Eq 1-8: acuity,
  Sobel gradient, binomial blur, B-spline resampling, contrast, rho, map in float32; the budget in double), prefixed
  ``fpsm_``; the images they read are bound to the FPSM shader's buffers.
* :func:`fxaa_glsl` translates FXAA's per-pixel kernel :func:`renderers.antialias.fxaa_pixel` (and its bilinear
  and clamped fetches), prefixed ``aa_``, in numba's own types: float32 (``f32``) where the CPU adds values of its
  float32 image, float64 elsewhere, all ``precise``, so that both backends take the same edge decisions bit for
  bit. The image is the shader's accessor ``aa_img(y, x, ch)`` (``Translator.bindings``, with ``img.shape``).
* :func:`warp_glsl` translates the forward grid warping of :mod:`renderers._warp` (a quad's depth-discontinuity
  test and the rasteriser of its two warped triangles), prefixed ``rep_``; the fragment is the shader's own
  (``Translator.externals``: a module function called by its GLSL name, not translated).
* :func:`projection_glsl` translates the pinhole camera of :mod:`renderers.projection` (a screen position's
  image-plane offsets and ray in precise double, the inverse in float), prefixed ``proj_``.
* :func:`lp_glsl` translates the LP buffer's per-pixel kernels of :mod:`renderers._lp` (a screen offset's column
  from the u(r) table; a screen pixel's bilinear fetch from the LP buffer, rows wrapped at the seam; whether an LP
  pixel is shaded; the filling of an LP row), prefixed ``lp_``; :func:`antialias_glsl` those of
  :mod:`renderers.antialias` (scipy's separable ``correlate1d`` at a pixel; the foveal Gaussian's band and pixel;
  FXAA's luma), prefixed ``aa_``. The images they read are bound to macros or image loads of the including shader
  (``img[y, x, ch]`` -> ``px_at(y, x)[ch]``), an image they write to a store (``Translator.stores``).
* :func:`gt_glsl` translates the GT sample positions and pixel filter of :mod:`renderers._gt` (double), prefixed
  ``gt_``; the samples and their positions are bound to the sample shader's buffers.
* :func:`constants_glsl` emits the shared constant table :mod:`renderers.constants`; :func:`int64_glsl` the
  64-bit integer helpers.

Types are inferred to a fixed point: a name is ``int`` when every value given to it is an integer expression,
``i64``/``u64`` (numba's ``np.int64``/``np.uint64``, on 32-bit halves) when it holds those, ``vec2``-``vec4`` for
tuples, otherwise ``float`` (``double`` in a double-precision closure). The translator knows the small Python
subset these kernels use (assignments, tuple unpacking, ``if``/``elif``/``else``, ``for ... in range``,
``while``, ``break``, ``continue``, ``return`` (also without a value: a ``void`` function), a call as a
statement, arithmetic, comparisons including chained ones, ``math`` functions and ``math.pi``/``math.inf``,
``np.clip``/``np.sqrt`` (numpy on the CPU's arrays, GLSL on scalars), ``a.shape[k]`` and
``a.size`` of a bound array ``a`` through bindings named ``"a.shape"``, ``"a.size"``; ``f32``: numba's float32, the
element type of a bound float32 array (``binding_types``), kept by ``+ - * /`` between two ``f32`` values,
``min``/``max``/``abs`` and conditionals, float64 with anything else) and raises ``NotImplementedError`` naming the
function and the construct otherwise (also for a name GLSL reserves, such as ``half``), so a kernel change that it
cannot follow fails loudly in the tests rather than drifting apart. In a function of ``Translator.precise`` every
float local, tuple temporary and returned value is ``precise`` (no fused multiply-add: the CPU's rounding).
Further:

* a tuple returned by a call is unpacked with its elements' types (``leaf, pdf = descend(...)``: an int element
  travels in the float vector, exact below 2^24, and is converted back);
* a function without a return value (a pixel kernel that only writes bound arrays) is ``void``;
* a float kernel may call a double-precision one that returns a scalar (``min(uniform(...), ONE_MINUS)``: its
  result converted to float, an int argument given as a uint64 counter ``uvec2(uint(x), 0u)``); other calls across
  precisions are refused;
* ``<<``, ``>>`` on ints; ``Translator.binding_types`` also types bound scalars (``n_leaves`` -> ``int``).
* numba's ``np.uint32`` arithmetic as GLSL ``uint`` (``+``, ``-``, ``*``, ``<<`` only inside ``np.uint32(...)``,
  which truncates numba's 64-bit result as GLSL wraps; integer constants above 2^31 - 1 are ``uint``), integer
  ``//`` (Python's floor, exact through double), the casts ``np.float32``/``np.float64`` (to the closure's
  precision: numba's ``float()`` of a float32 stays float32); calls of another translated module's kernels
  (``Translator.externals``: ``point`` -> ``fov_point``); image stores as assignment targets
  (``Translator.stores``).
"""

from __future__ import annotations

import ast
import functools
import inspect
import math

from ..constants import LC_ONE_MINUS_F32

#: The kernels translated (and their callees, found automatically).
FOVEATION_ROOTS = ("point",)
_MATH = {"atan": "fov_atan", "tan": "tan", "cos": "cos", "sin": "sin", "acos": "fov_acos", "sqrt": "sqrt",
         "exp": "exp", "log": "log", "floor": "floor", "ceil": "ceil", "log1p": "fov_log1p", "expm1": "fov_expm1"}
#: Float-accurate helpers: GPU math libraries may be coarse (Mesa's llvmpipe: acos 1.6e-4 absolute error, log
#: 3.5e-7 absolute near 1); these keep the mappings within ~1e-6 relative of the CPU's float64.
_HELPERS = """
// log1p / expm1: series near 0 (relative error < 1e-10 for |x| < 0.05), else through log / exp.
float fov_log1p(float x) {
    if (abs(x) < 0.05) return x * (1.0 - x * (0.5 - x * (1.0 / 3.0 - x * (0.25 - x * (0.2 - x * (1.0 / 6.0
        - x * (1.0 / 7.0)))))));
    return log(1.0 + x);
}
float fov_expm1(float x) {
    if (abs(x) < 0.05) return x * (1.0 + x * (0.5 + x * (1.0 / 6.0 + x * (1.0 / 24.0 + x * (1.0 / 120.0
        + x * (1.0 / 720.0))))));
    return exp(x) - 1.0;
}
// atan and acos: Cephes atanf / asinf polynomials (relative error ~2e-7 in float32).
float fov_atan(float x) {
    float a = abs(x), y = 0.0;
    if (a > 2.414213562373095) { y = 1.5707963267948966; a = -1.0 / a; }
    else if (a > 0.41421356237309503) { y = 0.7853981633974483; a = (a - 1.0) / (a + 1.0); }
    float z = a * a;
    y += (((8.05374449538e-2 * z - 1.38776856032e-1) * z + 1.99777106478e-1) * z - 3.33329491539e-1) * z * a + a;
    return x < 0.0 ? -y : y;
}
float fov_asin_small(float x) {   // |x| <= 0.5
    float z = x * x;
    return ((((4.2163199048e-2 * z + 2.4181311049e-2) * z + 4.5470025998e-2) * z + 7.4953002686e-2) * z
            + 1.6666752422e-1) * z * x + x;
}
float fov_acos(float x) {
    if (x < -0.5) return 3.141592653589793 - 2.0 * fov_asin_small(sqrt(0.5 * (1.0 + x)));
    if (x > 0.5) return 2.0 * fov_asin_small(sqrt(0.5 * (1.0 - x)));
    return 1.5707963267948966 - fov_asin_small(x);
}
float fov_atan2(float y, float x) {
    if (x > 0.0) return fov_atan(y / x);
    if (x < 0.0) return y >= 0.0 ? fov_atan(y / x) + 3.141592653589793 : fov_atan(y / x) - 3.141592653589793;
    return y > 0.0 ? 1.5707963267948966 : (y < 0.0 ? -1.5707963267948966 : 0.0);
}
"""


class _Fn:
    def __init__(self, node: ast.FunctionDef):
        self.node = node
        self.name = node.name
        self.params = [a.arg for a in node.args.args]
        self.ret = "float"
        #: the element types (``int`` or ``float``) of a tuple return, for typed unpacking at the call sites
        self.ret_elts: list[str] | None = None
        self.param_types = {p: "float" for p in self.params}
        self.var_types: dict[str, str] = {}
        self.calls: set[str] = set()
        self.real = "float"   # "double" for the functions of a double-precision closure


class Translator:
    """Translate functions of one module (see the module docstring for the supported subset)."""

    def __init__(self, module, prefix: str, array_param: str = "P", array_name: str = "FP", source: str | None = None,
                 bindings: dict[str, str] | None = None):
        self.module = module
        #: parameters that are not GLSL parameters but data the shader reads: name -> expression, with ``{0}``,
        #: ``{1}`` for the subscripts of an array (``bmin[k, a]`` -> ``node_min(k)[a]``) or none for a scalar
        #: (``n_leaves`` -> ``u_n_leaves``); ``array_param`` is the foveation kernels' one such array
        self.bindings = {array_param: f"{array_name}[{{0}}]", **(bindings or {})}
        #: float32 values of float64 constants whose float32 rounding would change their meaning (1 - 2^-53 -> 1)
        self.float32_values: dict[str, float] = {}
        #: the element type of a bound array that is not ``float`` (``cut`` -> ``int``)
        self.binding_types: dict[str, str] = {}
        #: functions called, not translated: name -> (GLSL name, return type). Those of another translated module
        #: (``point`` -> ``fov_point``) and those of this module that the shader writes itself (the GPU's fragment
        #: of the warped-grid rasteriser is a phase of atomics where the CPU depth-tests). The arrays bound here are
        #: dropped from their arguments (the callee reads its own), the bound scalars passed
        self.externals: dict[str, tuple[str, str]] = {}
        #: bound arrays that are written by a statement (an image): name -> template with ``{0}``, ``{1}`` for the
        #: subscripts and ``{value}`` (``lp[j, c] = v`` -> ``imageStore(lp, ivec2(c, j), v)``)
        self.stores: dict[str, str] = {}
        #: functions whose float locals are ``precise`` (no fused multiply-add: the rounding of the CPU's sums)
        self.precise: set[str] = set()
        self.prefix = prefix
        tree = ast.parse(source if source is not None else inspect.getsource(module))
        self.fns = {n.name: _Fn(n) for n in tree.body if isinstance(n, ast.FunctionDef)}
        self.consts = {k: v for k, v in vars(module).items()
                       if k.isupper() and isinstance(v, (int, float)) and not isinstance(v, bool)}
        from .. import constants as shared
        #: constants taken from the shared table (renderers/constants.py): declared once by constants_gen.glsl
        #: under their own names, not re-emitted with the prefix
        self.shared = {k for k, v in self.consts.items() if getattr(shared, k, None) == v}
        import numpy as np

        #: module-level np.uint64 constants (the random numbers' multipliers), emitted as uvec2(lo, hi)
        self.u64_consts = {k: int(v) for k, v in vars(module).items() if isinstance(v, np.uint64)}
        #: module-level np.uint32 constants (the GT jitter's hash), emitted as GLSL ``uint``
        self.u32_consts = {k: int(v) for k, v in vars(module).items() if isinstance(v, np.uint32)}

    # -- analysis ----------------------------------------------------------------------------------------------
    def closure(self, roots) -> list[str]:
        order, seen = [], set()

        def visit(name):
            if name in seen:
                return
            seen.add(name)
            fn = self.fns[name]
            for call in ast.walk(fn.node):
                if isinstance(call, ast.Call) and isinstance(call.func, ast.Name) and call.func.id in self.fns \
                        and call.func.id not in self.externals:
                    fn.calls.add(call.func.id)
                    visit(call.func.id)
            order.append(name)   # callees first: GLSL needs declarations before use

        for r in roots:
            visit(r)
        return order

    def precision_closure(self, double_roots=(), float_roots=()) -> tuple[list[str], list[str]]:
        """The closure of ``double_roots``, marked double precision (the CPU's float64 where float32 would change
        a result: textures, random numbers, budgets, camera rays), and the rest of the closure of
        ``float_roots`` (float32), each in declaration order."""
        doubles = self.closure(double_roots)
        floats = [n for n in self.closure(float_roots) if n not in doubles]
        for n in doubles:
            self.fns[n].real = "double"
        return doubles, floats

    def infer(self, names, root_params: dict | None = None) -> None:
        """Fixed point of variable, parameter and return types. A parameter is ``int`` when every call site
        passes an integer expression (``root_params`` gives the types of the roots' parameters)."""
        for name, types in (root_params or {}).items():
            self.fns[name].param_types.update(types)
        roots = set(root_params or {})
        for _ in range(20):
            changed = False
            conflicts: list[str] = []
            _join = functools.partial(_join_types, conflicts)
            site_types: dict[str, dict[str, set[str]]] = {}
            for name in names:
                fn = self.fns[name]
                assigned: dict[str, set[str]] = {}
                for node in ast.walk(fn.node):
                    if isinstance(node, ast.For):
                        assigned.setdefault(node.target.id, set()).add("int")
                    elif isinstance(node, ast.Assign):
                        self._collect_assign(fn, node.targets[0], node.value, assigned)
                    elif isinstance(node, ast.AugAssign):
                        assigned.setdefault(node.target.id, set()).add(self.etype(fn, node.value))
                    elif isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in self.fns:
                        callee = self.fns[node.func.id]
                        params = [q for q in callee.params if q not in self.bindings]
                        args = [a for a in node.args if not self._is_array(a)]
                        for p, a in zip(params, args):
                            site_types.setdefault(callee.name, {}).setdefault(p, set()).add(self.etype(fn, a))
                for var, types in assigned.items():
                    if var in fn.params:
                        continue
                    t = _join(fn.name, var, types)
                    if fn.var_types.get(var) != t:
                        fn.var_types[var] = t
                        changed = True
                rets = {self._ret_type(fn, r.value) for r in ast.walk(fn.node) if isinstance(r, ast.Return)}
                ret = _join(fn.name, "return value", rets) if rets else "void"   # a kernel that stores
                elts = self._ret_elts(fn)
                if fn.ret != ret or fn.ret_elts != elts:
                    fn.ret, fn.ret_elts = ret, elts
                    changed = True
            for name in names:
                if name in roots:
                    continue
                fn = self.fns[name]
                for p in fn.param_types:
                    if p in self.bindings:
                        continue
                    t = _join(name, p, site_types.get(name, {}).get(p, {"float"}))
                    if fn.param_types[p] != t:
                        fn.param_types[p] = t
                        changed = True
            if not changed:
                if conflicts:  # at the fixed point: a name really takes values of two types
                    raise NotImplementedError(conflicts[0])
                return
        raise NotImplementedError("type inference did not converge")

    def _collect_assign(self, fn, target, value, assigned):
        if isinstance(target, ast.Tuple):
            if isinstance(value, ast.Tuple):
                for t, v in zip(target.elts, value.elts):
                    self._collect_assign(fn, t, v, assigned)
            else:   # a call's tuple: its elements' types (ints travel in a float vector, exact below 2^24)
                elts = self._callee(value).ret_elts if self._callee(value) else None
                for k, t in enumerate(target.elts):
                    if isinstance(t, ast.Name):
                        want = elts[k] if elts and len(elts) == len(target.elts) else "float"
                        assigned.setdefault(t.id, set()).add(want)
        elif isinstance(target, ast.Name):
            if self.etype(fn, value) == "void":
                raise NotImplementedError(f"{fn.name}: {target.id} takes the value of a call that returns nothing")
            assigned.setdefault(target.id, set()).add(self.etype(fn, value))
        elif not (isinstance(target, ast.Subscript) and self._is_array(target.value)):
            raise NotImplementedError(f"{fn.name}: assignment to {ast.dump(target)}")

    def _callee(self, value) -> _Fn | None:
        """The translated function ``value`` calls, if it is such a call."""
        if isinstance(value, ast.Call) and isinstance(value.func, ast.Name):
            return self.fns.get(value.func.id)
        return None

    def _ret_elts(self, fn) -> list[str] | None:
        """Element types of ``fn``'s tuple returns (``int`` where every return gives an int there)."""
        tuples = [r.value.elts for r in ast.walk(fn.node)
                  if isinstance(r, ast.Return) and isinstance(r.value, ast.Tuple)]
        if not tuples or len({len(t) for t in tuples}) != 1:
            return None
        return ["int" if {self.etype(fn, t[k]) for t in tuples} == {"int"} else "float" for k in range(len(tuples[0]))]

    def _ret_type(self, fn, value):
        if value is None:
            return "void"
        if isinstance(value, ast.Tuple):
            if not 2 <= len(value.elts) <= 4:
                raise NotImplementedError(f"{fn.name}: tuple of {len(value.elts)} values (GLSL vectors hold 2-4)")
            return f"vec{len(value.elts)}"
        return self.etype(fn, value)

    def _is_array(self, node) -> bool:
        return isinstance(node, ast.Name) and node.id in self.bindings

    def _shape_key(self, e) -> str | None:
        """``"img.shape"`` for ``img.shape[k]``, ``"steps.size"`` for ``steps.size``, of a bound array; else None."""
        if isinstance(e, ast.Subscript) and isinstance(e.value, ast.Attribute) and e.value.attr == "shape":
            e = e.value
        elif not (isinstance(e, ast.Attribute) and e.attr == "size"):
            return None
        return f"{e.value.id}.{e.attr}" if self._is_array(e.value) else None

    def vtype(self, fn, name: str) -> str:
        if name in self.bindings and name in self.binding_types:   # a bound scalar (``kmax`` -> ``u_kmax``)
            return self.binding_types[name]
        if name in fn.param_types:
            return fn.param_types[name]
        if name in fn.var_types:
            return fn.var_types[name]
        if name in self.u64_consts:
            return "u64"
        if name in self.u32_consts:
            return "u32"
        v = self.consts.get(name)
        if v is not None:
            return ("u32" if v > 0x7FFFFFFF else "int") if isinstance(v, int) else "float"
        return "float"

    def etype(self, fn, e) -> str:
        if isinstance(e, ast.Constant):
            return "int" if isinstance(e.value, int) and not isinstance(e.value, bool) else "float"
        if isinstance(e, ast.Name):
            return self.vtype(fn, e.id)
        if isinstance(e, ast.BinOp):
            a, b = self.etype(fn, e.left), self.etype(fn, e.right)
            if isinstance(e.op, (ast.Div, ast.Pow)):
                return "f32" if a == b == "f32" and isinstance(e.op, ast.Div) else "float"
            if "i64" in (a, b):
                return "int" if isinstance(e.op, ast.BitAnd) else "i64"
            if "u64" in (a, b):
                return "u64"
            if "u32" in (a, b):
                return "u32" if {a, b} <= {"u32", "int"} else "float"
            if a == b == "f32" and isinstance(e.op, (ast.Add, ast.Sub, ast.Mult)):
                return "f32"   # numba: float32 op float32 stays float32; with a float64 or an int it is float64
            if type(e.op) in (ast.LShift, ast.RShift, ast.BitAnd, ast.BitOr, ast.BitXor):
                return "int"   # Python has no float bit operations
            return "int" if a == b == "int" else "float"
        if isinstance(e, (ast.Compare, ast.BoolOp)) or (isinstance(e, ast.UnaryOp) and isinstance(e.op, ast.Not)):
            return "bool"
        if isinstance(e, ast.Subscript) and self._is_array(e.value):
            return self.binding_types.get(e.value.id, "float")
        if self._shape_key(e) is not None:
            return "int"
        if isinstance(e, ast.UnaryOp):
            return self.etype(fn, e.operand)
        if isinstance(e, ast.IfExp):
            a, b = self.etype(fn, e.body), self.etype(fn, e.orelse)
            return a if a == b and a in ("int", "bool", "f32") else "float"
        if isinstance(e, ast.Call):
            f = e.func
            if isinstance(f, ast.Attribute) and isinstance(f.value, ast.Name) and f.value.id == "np" \
                    and f.attr in ("int64", "uint64", "uint32", "float32", "float64"):
                return {"int64": "i64", "uint64": "u64", "uint32": "u32", "float32": "float", "float64": "float"}[f.attr]
            if isinstance(f, ast.Name):
                if f.id == "int":
                    return "int"
                if f.id in ("min", "max", "abs"):
                    ts = {self.etype(fn, a) for a in e.args}
                    return ts.pop() if ts in ({"int"}, {"f32"}) else "float"
                if f.id in self.externals:
                    return self.externals[f.id][1]
                if f.id in self.fns:
                    return self.fns[f.id].ret
            return "float"
        return "float"

    # -- emission ----------------------------------------------------------------------------------------------
    def emit(self, names, helpers: bool = True, consts: bool = True) -> str:
        """GLSL of the functions ``names``, with the float helpers and the module's constants unless told not to
        (a second file of the same module, included after the first)."""
        out = [_HELPERS] if helpers else []
        types = {t for n in names for t in [*self.fns[n].var_types.values(), *self.fns[n].param_types.values()]}
        if types & {"i64", "u64"}:   # one copy per shader: the include is expanded once
            out.append('#include "int64_gen.glsl"')
        for k, v in sorted(self.u32_consts.items() if consts else ()):
            out.append(f"const uint {self.const_name(k)} = {v}u;")
        for k, v in sorted(self.u64_consts.items() if consts else ()):
            out.append(f"const uvec2 {self.const_name(k)} = uvec2({v & 0xFFFFFFFF}u, {v >> 32}u);")
        for k, v in sorted(self.consts.items() if consts else ()):
            if k in self.shared:
                continue
            if isinstance(v, int):
                out.append(f"const uint {self.const_name(k)} = {v}u;" if v > 0x7FFFFFFF
                           else f"const int {self.const_name(k)} = {v};")
            else:
                out.append(f"const float {self.const_name(k)} = {_flt(v)};")
        out.append("")
        body = [self.emit_fn(self.fns[name]) for name in names]
        if any("py_imod(" in f for f in body):   # once per shader, whichever generated file comes first
            out.insert(len(out) - 1, _IMOD_HELPER)
        return "\n".join(out + body) + "\n"

    def emit_fn(self, fn: _Fn) -> str:
        for name in [*(p for p in fn.params if p not in self.bindings), *fn.var_types]:
            if name in _GLSL_RESERVED:
                raise NotImplementedError(f"{fn.name}: name '{name}' is reserved in GLSL")
        params = ", ".join(f"{self.tname(fn, fn.param_types[p])} {p}" for p in fn.params if p not in self.bindings)
        lines = [f"{self.tname(fn, fn.ret)} {self.glsl_name(fn.name)}({params}) {{"]
        loop_vars = {n.target.id for n in ast.walk(fn.node) if isinstance(n, ast.For)}
        precise = "precise " if fn.name in self.precise else ""
        for var, t in sorted(fn.var_types.items()):
            if var not in loop_vars and var != "_":
                lines.append(f"    {precise if t in ('float', 'f32') else ''}{self.tname(fn, t)} {var};")
        self._tmp = 0
        body = fn.node.body
        if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant):
            body = body[1:]
        for st in body:
            lines += self.stmt(fn, st, 1)
        lines.append("}")
        return "\n".join(lines) + "\n"

    def stmt(self, fn, st, depth) -> list[str]:
        pad = "    " * depth
        if isinstance(st, ast.Assign):
            target, value = st.targets[0], st.value
            if isinstance(target, ast.Tuple):
                if isinstance(value, ast.Tuple):
                    tmps, lines = [], []
                    for v in value.elts:  # evaluate all right-hand sides first (Python semantics)
                        self._tmp += 1
                        tmp = f"_v{self._tmp}"
                        tmps.append(tmp)
                        t = self.etype(fn, v)
                        lines.append(f"{pad}{self._precise(fn, t)}{self.tname(fn, t)} {tmp} = {self.expr(fn, v)};")
                    for t, tmp in zip(target.elts, tmps):
                        lines.append(f"{pad}{t.id} = {tmp};")
                    return lines
                self._tmp += 1
                tmp = f"_t{self._tmp}"
                have = self.etype(fn, value)
                if have != f"vec{len(target.elts)}":
                    raise NotImplementedError(f"{fn.name}: unpacking {len(target.elts)} names from a {have}")
                lines = [f"{pad}{self.tname(fn, have)} {tmp} = {self.expr(fn, value)};"]
                for comp, t in zip("xyzw", target.elts):
                    if t.id != "_":
                        v = f"{tmp}.{comp}"
                        lines.append(f"{pad}{t.id} = {f'int({v})' if self.vtype(fn, t.id) == 'int' else v};")
                return lines
            if isinstance(target, ast.Subscript) and getattr(target.value, "id", None) in self.stores:   # image
                idx = target.slice.elts if isinstance(target.slice, ast.Tuple) else [target.slice]
                value = self.cast(fn, value, self.etype(fn, target))
                return [pad + self.stores[target.value.id].format(*(self.expr(fn, i) for i in idx), value=value)
                        + ";"]
            if isinstance(target, ast.Subscript):   # an element of a bound array
                return [f"{pad}{self.expr(fn, target)} = {self.cast(fn, value, self.etype(fn, target))};"]
            return [f"{pad}{target.id} = {self.cast(fn, value, self.vtype(fn, target.id))};"]
        if isinstance(st, ast.AugAssign):
            if self.vtype(fn, st.target.id) in ("i64", "u64") or isinstance(st.op, ast.Mod):   # x = x op y
                binop = ast.BinOp(left=ast.Name(id=st.target.id, ctx=ast.Load()), op=st.op, right=st.value)
                return [f"{pad}{st.target.id} = {self.expr(fn, binop)};"]
            op = _BINOPS[type(st.op)]
            return [f"{pad}{st.target.id} {op}= {self.expr(fn, st.value)};"]
        if isinstance(st, ast.Return):
            if st.value is None:
                return [f"{pad}return;"]
            if isinstance(st.value, ast.Tuple):
                vals = ", ".join(self.cast(fn, v, "float") for v in st.value.elts)
                value, t = f"{self.tname(fn, self._ret_type(fn, st.value))}({vals})", self._ret_type(fn, st.value)
            else:
                value, t = self.cast(fn, st.value, fn.ret), fn.ret
            if not self._precise(fn, t):
                return [f"{pad}return {value};"]
            self._tmp += 1   # through a precise temporary: no fused multiply-add in the returned expression either
            return [f"{pad}precise {self.tname(fn, t)} _r{self._tmp} = {value};", f"{pad}return _r{self._tmp};"]
        if isinstance(st, ast.If):
            lines = [f"{pad}if ({self.cond(fn, st.test)}) {{"]
            for s in st.body:
                lines += self.stmt(fn, s, depth + 1)
            if st.orelse:
                lines.append(f"{pad}}} else {{")
                for s in st.orelse:
                    lines += self.stmt(fn, s, depth + 1)
            lines.append(f"{pad}}}")
            return lines
        if isinstance(st, ast.For):
            it = st.iter
            if not (isinstance(it, ast.Call) and isinstance(it.func, ast.Name) and it.func.id == "range"):
                raise NotImplementedError(f"{fn.name}: for loop over {ast.dump(it)}")
            args = [self.expr(fn, a) for a in it.args]
            lo, hi = (args[0], args[1]) if len(args) == 2 else ("0", args[0])
            v = st.target.id
            lines = [f"{pad}for (int {v} = {lo}; {v} < {hi}; {v}++) {{"]
            for s in st.body:
                lines += self.stmt(fn, s, depth + 1)
            lines.append(f"{pad}}}")
            return lines
        if isinstance(st, ast.While) and not st.orelse:
            lines = [f"{pad}while ({self.cond(fn, st.test)}) {{"]
            for s in st.body:
                lines += self.stmt(fn, s, depth + 1)
            lines.append(f"{pad}}}")
            return lines
        if isinstance(st, (ast.Break, ast.Continue)):
            return [f"{pad}{'break' if isinstance(st, ast.Break) else 'continue'};"]
        if isinstance(st, ast.Expr) and isinstance(st.value, ast.Call):   # a call for its effect (an external)
            return [f"{pad}{self.expr(fn, st.value)};"]
        if isinstance(st, ast.Expr) and isinstance(st.value, ast.Constant):
            return []
        raise NotImplementedError(f"{fn.name}: statement {type(st).__name__}")

    def const_name(self, name: str) -> str:
        return self.prefix.upper() + name.lstrip("_")

    def glsl_name(self, name: str) -> str:
        """The GLSL name of a translated function: the prefix and the Python name without leading underscores
        (GLSL reserves names containing ``__``)."""
        return self.prefix + name.lstrip("_")

    def _precise(self, fn, t: str) -> str:
        """``precise `` for a float value of a function in ``self.precise``."""
        return "precise " if fn.name in self.precise and (t in ("float", "f32") or t.startswith("vec")) else ""

    def tname(self, fn, t: str) -> str:
        """The GLSL type of an inferred type in ``fn`` (``float`` is ``fn``'s precision; ``f32`` is numba's float32
        in a double-precision function: a value read from a float32 array, and sums of such values)."""
        if t == "f32":
            return "float"
        if t in ("i64", "u64"):
            return "uvec2"
        if t == "u32":
            return "uint"
        if fn.real == "double" and (t == "float" or t.startswith("vec")):
            return "double" if t == "float" else "d" + t
        return t

    def cast(self, fn, e, want: str) -> str:
        text = self.expr(fn, e)
        have = self.etype(fn, e)
        if want == "float" and have in ("int", "f32", "u32"):
            return f"{fn.real}({text})"
        if want != have and "u32" in (want, have):
            raise NotImplementedError(f"{fn.name}: {have} used as {want}")
        if want == "i64" and have == "int":
            return f"i64_from({text})"
        if want == "u64" and have == "int":   # a non-negative int (a sample slot) as a uint64 counter
            return f"uvec2(uint({text}), 0u)"
        if want != have and "i64" in (want, have):
            raise NotImplementedError(f"{fn.name}: {have} used as {want}")
        return text

    def cond(self, fn, e) -> str:
        """``e`` as a GLSL bool (Python's truth of an int or float: != 0)."""
        t = self.etype(fn, e)
        if t == "bool":
            return self.expr(fn, e)
        if t in ("int", "float"):
            return f"({self.expr(fn, e)} != {'0' if t == 'int' else self.lit(fn, 0.0)})"
        raise NotImplementedError(f"{fn.name}: truth value of a {t}")

    def lit(self, fn, v: float) -> str:
        text = _flt(float(v))
        return text + "LF" if fn.real == "double" and not text.startswith("(") else text

    def expr(self, fn, e) -> str:
        if isinstance(e, ast.Constant):
            if isinstance(e.value, bool):
                return "true" if e.value else "false"
            if isinstance(e.value, int):
                return str(e.value)
            return self.lit(fn, e.value)
        if isinstance(e, ast.Name):
            if e.id in self.shared:
                return e.id
            if e.id in self.bindings:
                return self.bindings[e.id]
            if e.id in self.u64_consts or e.id in self.u32_consts:
                return self.const_name(e.id)
            if e.id in self.consts:
                if fn.real == "double" and isinstance(self.consts[e.id], float):
                    return self.lit(fn, self.consts[e.id])   # the float64 value, not its float32 constant
                if e.id in self.float32_values:
                    return self.lit(fn, self.float32_values[e.id])
                return self.const_name(e.id)
            return e.id
        key = self._shape_key(e)
        if key is not None:   # img.shape[k], steps.size of a bound array: its own binding ("img.shape": "..{0}..")
            if key not in self.bindings:
                raise NotImplementedError(f"{fn.name}: {key} of an array without a '{key}' binding")
            return self.bindings[key].format(*([self.expr(fn, e.slice)] if isinstance(e, ast.Subscript) else []))
        if isinstance(e, ast.Attribute):
            if isinstance(e.value, ast.Name) and e.value.id == "math" and e.attr in ("pi", "inf"):
                return self.lit(fn, getattr(math, e.attr))
            raise NotImplementedError(f"{fn.name}: attribute {ast.dump(e)}")
        if isinstance(e, ast.Subscript):
            idx = e.slice.elts if isinstance(e.slice, ast.Tuple) else [e.slice]
            if self._is_array(e.value):
                return self.bindings[e.value.id].format(*(self.expr(fn, i) for i in idx))
            if isinstance(e.value, ast.Name) and self.vtype(fn, e.value.id) in ("vec3", "vec4") and len(idx) == 1:
                return f"{e.value.id}[{self.expr(fn, idx[0])}]"
            raise NotImplementedError(f"{fn.name}: subscript of {ast.dump(e.value)}")
        if isinstance(e, ast.BinOp):
            a, b = self.expr(fn, e.left), self.expr(fn, e.right)
            if "i64" in (self.etype(fn, e.left), self.etype(fn, e.right)):
                return self.i64_op(fn, e)
            if "u64" in (self.etype(fn, e.left), self.etype(fn, e.right)):
                return self.u64_op(fn, e)
            if self.etype(fn, e) == "u32":
                return self.u32_op(fn, e, wrapped=False)
            if isinstance(e.op, ast.FloorDiv) and self.etype(fn, e) == "int":   # Python floors; exact in double
                return f"int(floor(double({a}) / double({b})))"
            if isinstance(e.op, ast.Mod) and self.etype(fn, e.left) == self.etype(fn, e.right) == "int":
                return f"py_imod({a}, {b})"   # Python's sign (of the divisor); GLSL's % is undefined below 0
            if isinstance(e.op, ast.Mod) and "float" in (self.etype(fn, e.left), self.etype(fn, e.right)):
                return f"mod({self.cast(fn, e.left, 'float')}, {self.cast(fn, e.right, 'float')})"  # Python's sign
            if isinstance(e.op, ast.Pow):
                return f"pow({self.cast(fn, e.left, 'float')}, {self.cast(fn, e.right, 'float')})"
            if isinstance(e.op, ast.Div):
                if self.etype(fn, e) == "f32":
                    return f"({a} / {b})"
                return f"({self.cast(fn, e.left, 'float')} / {self.cast(fn, e.right, 'float')})"
            if type(e.op) not in _BINOPS:
                raise NotImplementedError(f"{fn.name}: operator {type(e.op).__name__}")
            ta, tb = self.etype(fn, e.left), self.etype(fn, e.right)
            if ta != tb:  # GLSL converts implicitly, but say it (and keep int/float mixing visible)
                a = f"{fn.real}({a})" if ta in ("int", "f32") else a
                b = f"{fn.real}({b})" if tb in ("int", "f32") else b
            return f"({a} {_BINOPS[type(e.op)]} {b})"
        if isinstance(e, ast.UnaryOp):
            if isinstance(e.op, ast.USub):
                return f"(-{self.expr(fn, e.operand)})"
            if isinstance(e.op, ast.Not):
                return f"(!{self.cond(fn, e.operand)})"
            raise NotImplementedError(f"{fn.name}: unary {type(e.op).__name__}")
        if isinstance(e, ast.BoolOp):
            op = " && " if isinstance(e.op, ast.And) else " || "
            return "(" + op.join(self.cond(fn, v) for v in e.values) + ")"
        if isinstance(e, ast.Compare):
            terms, left = [], e.left   # a <= b <= c: (a <= b) && (b <= c), b being a name or a constant
            for op, right in zip(e.ops, e.comparators):
                if type(op) not in _CMPOPS:
                    raise NotImplementedError(f"{fn.name}: comparison {type(op).__name__}")
                if len(e.ops) > 1 and not isinstance(right, (ast.Name, ast.Constant)):
                    raise NotImplementedError(f"{fn.name}: chained comparison through an expression")
                terms.append(f"({self.expr(fn, left)} {_CMPOPS[type(op)]} {self.expr(fn, right)})")
                left = right
            return terms[0] if len(terms) == 1 else "(" + " && ".join(terms) + ")"
        if isinstance(e, ast.IfExp):
            want = self.etype(fn, e)
            return (f"({self.cond(fn, e.test)} ? {self.cast(fn, e.body, want)} : "
                    f"{self.cast(fn, e.orelse, want)})")
        if isinstance(e, ast.Call):
            return self.call(fn, e)
        raise NotImplementedError(f"{fn.name}: expression {type(e).__name__}")

    def i64_op(self, fn, e) -> str:
        """numba's int64 arithmetic (the texture hash) on (lo, hi) halves: ``+``, ``^``, ``*`` and ``&`` by a
        constant, ``>>`` (arithmetic) by a constant below 32."""
        ta, tb = self.etype(fn, e.left), self.etype(fn, e.right)
        a, b = self.expr(fn, e.left), self.expr(fn, e.right)
        const = e.right.value if isinstance(e.right, ast.Constant) and isinstance(e.right.value, int) else None
        if isinstance(e.op, ast.Add):
            return f"i64_add({self.cast(fn, e.left, 'i64')}, {self.cast(fn, e.right, 'i64')})"
        if isinstance(e.op, ast.BitXor) and ta == tb == "i64":
            return f"({a} ^ {b})"
        if isinstance(e.op, ast.Mult) and ta == "i64" and const is not None and 0 <= const < 2 ** 32:
            return f"i64_mul({a}, {const}u)"
        if isinstance(e.op, ast.RShift) and ta == "i64" and const is not None and 0 < const < 32:
            return f"i64_sar({a}, {const})"
        if isinstance(e.op, ast.BitAnd) and ta == "i64" and const is not None and 0 <= const < 2 ** 31:
            return f"int({a}.x & {const}u)"
        raise NotImplementedError(f"{fn.name}: int64 operation {ta} {type(e.op).__name__} {tb}"
                                  + ("" if const is None else f" {const}"))

    def u64_op(self, fn, e) -> str:
        """numba's uint64 arithmetic (the counter-based random numbers) on (lo, hi) halves: ``+``, ``*``, ``^``
        and ``>>`` by a constant below 32, all modulo 2^64."""
        ta, tb = self.etype(fn, e.left), self.etype(fn, e.right)
        a, b = self.expr(fn, e.left), self.expr(fn, e.right)
        shift = _const_int(e.right)
        if ta == tb == "u64" and type(e.op) in (ast.Add, ast.Mult, ast.BitXor):
            return {ast.Add: f"i64_add({a}, {b})", ast.Mult: f"u64_mul({a}, {b})",
                    ast.BitXor: f"({a} ^ {b})"}[type(e.op)]
        if ta == "u64" and isinstance(e.op, ast.RShift) and shift is not None and 0 < shift < 32:
            return f"u64_shr({a}, {shift})"
        raise NotImplementedError(f"{fn.name}: uint64 operation {ta} {type(e.op).__name__} {tb}")

    def _arg(self, fn, callee, a, p: str) -> str:
        """Argument ``a`` of ``fn``'s call of ``callee`` for parameter ``p`` (an int given to a float parameter of a
        double-precision kernel becomes a double)."""
        want = callee.param_types[p]
        if callee.real != fn.real and want == "float" and self.etype(fn, a) == "int":
            return f"{callee.real}({self.expr(fn, a)})"
        return self.cast(fn, a, want)

    def u32_op(self, fn, e, wrapped: bool) -> str:
        """numba's arithmetic on ``np.uint32`` values (the GT sample hash) as GLSL ``uint``: ``^``, ``&``, ``|``,
        ``>>``, ``%`` anywhere; ``+``, ``-``, ``*``, ``<<`` only ``wrapped`` in ``np.uint32(...)`` (numba widens them
        to 64 bits, GLSL wraps modulo 2^32: the same value only once truncated). Integer operands become ``uint``."""
        ops = {ast.BitXor: "^", ast.BitAnd: "&", ast.BitOr: "|", ast.RShift: ">>", ast.Mod: "%"}
        wide = {ast.Add: "+", ast.Sub: "-", ast.Mult: "*", ast.LShift: "<<"}
        if type(e.op) not in ops and not (wrapped and type(e.op) in wide):
            raise NotImplementedError(f"{fn.name}: uint32 operation {type(e.op).__name__}"
                                      + ("" if type(e.op) not in wide else " outside np.uint32(...)"))

        def operand(x):
            c = _const_int(x)
            if c is not None and not isinstance(x, ast.Call):
                return f"{c}u"
            return self.expr(fn, x) if self.etype(fn, x) == "u32" else f"uint({self.expr(fn, x)})"

        return f"({operand(e.left)} {({**ops, **wide})[type(e.op)]} {operand(e.right)})"

    def call(self, fn, e) -> str:
        f = e.func
        if isinstance(f, ast.Attribute) and isinstance(f.value, ast.Name) and f.value.id == "np" \
                and f.attr == "uint32":   # truncation to 32 bits: GLSL's uint arithmetic wraps by itself
            a = e.args[0]
            if isinstance(a, ast.BinOp) and self.etype(fn, a) == "u32":
                return self.u32_op(fn, a, wrapped=True)
            if self.etype(fn, a) in ("int", "u32"):
                return self.expr(fn, a) if self.etype(fn, a) == "u32" else f"uint({self.expr(fn, a)})"
            raise NotImplementedError(f"{fn.name}: np.uint32 of a {self.etype(fn, a)}")
        if isinstance(f, ast.Attribute) and isinstance(f.value, ast.Name) and f.value.id == "np" \
                and f.attr == "int64":
            return f"i64_from(int({self.expr(fn, e.args[0])}))"
        if isinstance(f, ast.Attribute) and isinstance(f.value, ast.Name) and f.value.id == "np" \
                and f.attr == "uint64":
            if _const_int(e) is not None:
                return f"uvec2({_const_int(e) & 0xFFFFFFFF}u, {_const_int(e) >> 32}u)"
            if self.etype(fn, e.args[0]) == "u64":
                return self.expr(fn, e.args[0])
            raise NotImplementedError(f"{fn.name}: np.uint64 of a {self.etype(fn, e.args[0])}")
        if isinstance(f, ast.Attribute) and isinstance(f.value, ast.Name) and f.value.id == "np" \
                and f.attr in ("float32", "float64"):   # in a double closure float32 rounds, as on the CPU
            x = self.cast(fn, e.args[0], "float")
            return f"double(float({x}))" if f.attr == "float32" and fn.real == "double" else x
        if isinstance(f, ast.Name) and f.id == "float" and self.etype(fn, e.args[0]) == "u64":
            return f"u64_to_{fn.real}({self.expr(fn, e.args[0])})"
        if isinstance(f, ast.Attribute) and isinstance(f.value, ast.Name) and f.value.id == "math":
            args = [self.cast(fn, a, "float") for a in e.args]
            if f.attr == "hypot":
                return f"length(vec2({args[0]}, {args[1]}))"
            if f.attr == "atan2":
                return f"fov_atan2({args[0]}, {args[1]})"
            if f.attr in _MATH:
                return f"{_MATH[f.attr]}({', '.join(args)})"
            raise NotImplementedError(f"{fn.name}: math.{f.attr}")
        if isinstance(f, ast.Attribute) and isinstance(f.value, ast.Name) and f.value.id == "np" \
                and f.attr == "clip" and len(e.args) == 3:   # numpy on arrays, GLSL clamp on scalars
            a, lo, hi = (self.cast(fn, x, "float") for x in e.args)
            return f"clamp({a}, {lo}, {hi})"
        if isinstance(f, ast.Attribute) and isinstance(f.value, ast.Name) and f.value.id == "np" \
                and f.attr == "sqrt" and len(e.args) == 1:   # likewise (renderers/projection.py on arrays)
            return f"sqrt({self.cast(fn, e.args[0], 'float')})"
        if isinstance(f, ast.Name):
            if f.id == "int":
                return f"int({self.expr(fn, e.args[0])})"
            if f.id in ("min", "max"):
                want = self.etype(fn, e)
                a, b = (self.cast(fn, x, want) for x in e.args)
                return f"{f.id}({a}, {b})"
            if f.id == "abs":
                return f"abs({self.expr(fn, e.args[0])})"
            if f.id in self.externals:
                args = ", ".join(self.expr(fn, a) for a in e.args   # bound arrays dropped, bound scalars kept
                                 if not (self._is_array(a) and ("{0}" in self.bindings[a.id]
                                                                or not self.bindings[a.id])))
                return f"{self.externals[f.id][0]}({args})"
            if f.id in self.fns:
                callee = self.fns[f.id]
                narrow = callee.real == "double" and fn.real == "float"   # a double kernel's result as a float
                if callee.real != fn.real and not (narrow and callee.ret in ("float", "int")):
                    raise NotImplementedError(f"{fn.name}: call of {f.id} across precisions ({fn.real} -> "
                                              f"{callee.real})")
                params = [p for p in callee.params if p not in self.bindings]
                args = [a for a in e.args if not self._is_array(a)]
                text = ", ".join(self._arg(fn, callee, a, p) for p, a in zip(params, args))
                if narrow and callee.ret == "float":
                    return f"float({self.glsl_name(f.id)}({text}))"
                return f"{self.glsl_name(f.id)}({text})"
        raise NotImplementedError(f"{fn.name}: call of {ast.dump(f)}")


def _join_types(conflicts: list, fn: str, what: str, types: set[str]) -> str:
    """One type for the values given to a name: itself when they agree, ``float`` for ints and floats mixed;
    otherwise ``float`` for now, the conflict noted in ``conflicts`` (an error if it remains at the fixed point)."""
    if len(types) == 1:
        return next(iter(types))
    if types and types <= {"int", "float", "f32"}:
        return "float"
    conflicts.append(f"{fn}: {what} takes values of types {sorted(types)}")
    other = sorted(types - {"int", "float", "bool"})   # e.g. h = h ^ (h >> 13): h's own float guess yields
    return other[0] if len(other) == 1 else "float"


#: numba's int64 arithmetic on two 32-bit halves (lo, hi), two's complement: what the texture hash needs.
_I64_HELPERS = """
uvec2 i64_from(int x) { return uvec2(uint(x), x < 0 ? 0xFFFFFFFFu : 0u); }
uvec2 i64_add(uvec2 a, uvec2 b) {
    uint carry;
    uint lo = uaddCarry(a.x, b.x, carry);
    return uvec2(lo, a.y + b.y + carry);
}
uvec2 i64_mul(uvec2 a, uint c) {   // a c mod 2^64
    uint hi, lo;
    umulExtended(a.x, c, hi, lo);
    return uvec2(lo, hi + a.y * c);
}
uvec2 i64_sar(uvec2 a, int s) {    // arithmetic shift right, 0 < s < 32
    return uvec2((a.x >> s) | (a.y << (32 - s)), uint(int(a.y) >> s));
}
uvec2 u64_mul(uvec2 a, uvec2 b) {  // a b mod 2^64
    uint hi, lo;
    umulExtended(a.x, b.x, hi, lo);
    return uvec2(lo, hi + a.x * b.y + a.y * b.x);
}
uvec2 u64_shr(uvec2 a, int s) {    // logical shift right, 0 < s < 32
    return uvec2((a.x >> s) | (a.y << (32 - s)), a.y >> s);
}
double u64_to_double(uvec2 a) { return double(a.y) * 4294967296.0LF + double(a.x); }   // exact below 2^53
"""


#: Python's integer ``%`` (the result has the divisor's sign; GLSL leaves ``%`` of negative operands undefined).
_IMOD_HELPER = """#ifndef PY_IMOD
#define PY_IMOD
int py_imod(int a, int b) {
    int r = abs(a) % abs(b);
    r = a < 0 ? -r : r;
    return (r != 0 && (r < 0) != (b < 0)) ? r + b : r;
}
#endif"""


def _const_int(e) -> int | None:
    """The value of an integer literal or of ``np.uint64(literal)``, else None."""
    if isinstance(e, ast.Constant) and isinstance(e.value, int) and not isinstance(e.value, bool):
        return e.value
    if isinstance(e, ast.Call) and isinstance(e.func, ast.Attribute) and e.func.attr == "uint64" and e.args:
        return _const_int(e.args[0])
    return None


#: GLSL keywords and reserved words that are valid Python names (GLSL 4.30 §3.6); a kernel must not use them.
_GLSL_RESERVED = frozenset(
    "attribute const uniform varying buffer shared coherent volatile restrict readonly writeonly layout centroid "
    "flat smooth noperspective patch sample subroutine in out inout invariant precise discard lowp mediump highp "
    "precision common partition active asm class union enum typedef template this resource goto inline noinline "
    "public static extern external interface long short half fixed unsigned superp input output filter sizeof cast "
    "namespace using bool int uint float double true false switch case default do struct void".split())

_BINOPS = {ast.Add: "+", ast.Sub: "-", ast.Mult: "*", ast.Mod: "%", ast.BitAnd: "&", ast.BitOr: "|", ast.RShift: ">>",
           ast.BitXor: "^", ast.LShift: "<<"}
_CMPOPS = {ast.Lt: "<", ast.LtE: "<=", ast.Gt: ">", ast.GtE: ">=", ast.Eq: "==", ast.NotEq: "!="}


def _header(module) -> str:
    """The first line of a file generated from ``module``."""
    return f"// Generated from {module.__name__.replace('.', '/')}.py by renderers/gpu/codegen.py: do not edit.\n"


def _flt(v: float) -> str:
    if math.isinf(v):
        return "(1.0 / 0.0)" if v > 0 else "(-1.0 / 0.0)"
    text = repr(float(v))
    return text if ("e" in text or "." in text) else text + ".0"


@functools.lru_cache(maxsize=None)
def foveation_glsl() -> str:
    """GLSL of the foveation kernels: ``fov_point(method, direction, a, b)`` and everything it calls."""
    from ..foveation import _kernels

    tr = Translator(_kernels, "fov_")
    names = tr.closure(FOVEATION_ROOTS)
    tr.infer(names, {"point": {"method": "int", "direction": "int"}})
    return _header(_kernels) \
        + tr.emit(names)


def shade_glsl(module=None) -> str:
    """GLSL of the shading kernels of :mod:`renderers._shade` (textures and the value-noise hash in double
    precision, the BRDF lobes and light terms in float), prefixed ``shade_``. ``module``: another module of the
    same kernels (tests translate a changed copy)."""
    if module is None:
        return _shade_glsl_cached()
    return _shade_glsl(module)


@functools.lru_cache(maxsize=None)
def _shade_glsl_cached() -> str:
    from .. import _shade

    return _shade_glsl(_shade)


def _shade_glsl(module) -> str:
    source = inspect.getsource(module)
    tr = Translator(module, "shade_", source=source)
    doubles, floats = tr.precision_closure(module.GLSL_DOUBLE_ROOTS, module.GLSL_FLOAT_ROOTS)
    int_params = {"texture_weight": {"kind": "int"}, "light_direction": {"kind": "int"},
                  "irradiance_factor": {"kind": "int"}}
    tr.infer(doubles + floats, {r: int_params.get(r, {}) for r in (*module.GLSL_DOUBLE_ROOTS,
                                                                       *module.GLSL_FLOAT_ROOTS)})
    return _header(module) + '#include "constants_gen.glsl"\n' + tr.emit(doubles + floats, helpers=False)


def lights_glsl(module=None, roots: str = "GLSL_LIGHT_ROOTS") -> str:
    """GLSL of the kernels of :mod:`renderers._shade` that read the scene's tables (``roots``: the names in
    ``GLSL_LIGHT_ROOTS``: a hit's material terms, a light's unshadowed contribution, a shadow ray's direction and
    length; ``GLSL_POINT_ROOTS``: a shading point's light loop), prefixed ``shade_`` like the kernels of
    ``shade_gen.glsl`` they call. The tables are the shader's images (``scene.glsl``: ``material(m, c)`` is column
    ``c`` of ``mat_f``; 3 texels per light: position | kind, intensity | cast, direction); the hit's outputs its
    record ``hit_surf``; a point's per-light outputs samples.comp's arrays ``contrib``, ``lum``.
    ``module``: another module of the same kernels (tests translate a changed copy)."""
    if module is None:
        return _lights_glsl_cached(roots)
    return _lights_glsl(module, roots)


@functools.lru_cache(maxsize=None)
def _lights_glsl_cached(roots: str) -> str:
    from .. import _shade

    return _lights_glsl(_shade, roots)


def _lights_glsl(module, roots: str) -> str:
    light = "fetchf(t_lights, 3 * ({0})"
    tr = Translator(module, "shade_", source=inspect.getsource(module), bindings={
        "L_kind": f"int({light}).w)", "L_pos": f"{light})[{{1}}]", "L_int": f"{light} + 1)[{{1}}]",
        "L_dir": f"{light} + 2)[{{1}}]", "mat_f": "material({0}, {1})", "ambient": "u_ambient[{0}]",
        "albedo": "hit_surf.a[{1}]", "base": "hit_surf.base[{1}]", "ks": "hit_surf.ks[{1}]",
        "P": "hit_surf.p[{1}]", "Ng": "hit_surf.n[{1}]", "exponent": "hit_surf.s_exp",
        "mat_i": "int(material({0}, 14))",   # the texture kind (mat_i[m, 0]): column 14 of the material image
        "contrib": "contrib[{1}][{2}]", "lum": "lum[{0}]"})
    tr.binding_types.update({"L_kind": "int", "mat_i": "int"})
    tr.precision_closure(module.GLSL_DOUBLE_ROOTS)   # shade_gen.glsl's textures: double, their results narrowed
    names = tr.closure(getattr(module, roots))
    tr.infer(names, {r: {"j": "int", "i": "int", "m": "int", "k": "int"} for r in getattr(module, roots)})
    # the callees are shade_gen.glsl's and lights_gen.glsl's (included before): only the roots are emitted here
    return _header(module) + "\n".join(tr.emit_fn(tr.fns[r]) for r in getattr(module, roots))
#: Lightcuts kernels emitted on their own (``lc_shade_gen.glsl``): they call functions the including shader defines
#: (``shade_pixel``'s ``blocked``: lc_shade.comp's shadow rays).
LC_OWN_FILE = ("shade_pixel",)


@functools.lru_cache(maxsize=None)
def lightcuts_glsl() -> str:
    """``lightcuts_gen.glsl``: every kernel of :func:`_lightcuts` but those of :data:`LC_OWN_FILE`."""
    tr, names = _lightcuts()
    return "// Generated from renderers/lightcuts/_kernels.py and multires.py by renderers/gpu/codegen.py: " \
        "do not edit.\n" + tr.emit([n for n in names if n not in LC_OWN_FILE], helpers=False)


@functools.lru_cache(maxsize=None)
def lightcuts_shade_glsl() -> str:
    """``lc_shade_gen.glsl``: the kernels of :data:`LC_OWN_FILE` (their callees are in ``lightcuts_gen.glsl``)."""
    from ..lightcuts import _kernels

    tr, _ = _lightcuts()
    return _header(_kernels) \
        + "".join(tr.emit_fn(tr.fns[n]) for n in LC_OWN_FILE)


@functools.lru_cache(maxsize=None)
def lightcuts_bounce_glsl() -> str:
    """``lc_bounce_gen.glsl``: the pixel kernels of :data:`LC_BOUNCE_ROOTS` (the CPU's bounce shading in
    ``glossy.glossy_pass``, through ``sampling.stochastic_lightcuts``) for one glossy ray's hit of
    ``lc_glossy.comp``, prefixed ``lcb_``: its point, id and samples are the shader's ``bn_*`` variables
    (:data:`LC_BOUNCE`), its shadow ray ``lcb_blocked(s)``; their callees are ``lightcuts_gen.glsl``'s."""
    from ..lightcuts import _kernels

    tr, _ = _lightcuts(bounce=True)
    return _header(_kernels) \
        + "".join(tr.emit_fn(tr.fns[n]) for n in LC_BOUNCE_ROOTS)


#: The per-pixel kernels the glossy pass's bounce runs (cut, one light per live node, the shadowed estimate) ...
LC_BOUNCE_ROOTS = ("cut_pixel", "sample_pixel", "shade_pixel")
#: ... and their pixel arrays in lc_glossy.comp: the one point (the ray's hit) of the shader's ``bn_*`` globals
LC_BOUNCE = {"pos": "bn_p", "nrm": "bn_n", "albedo": "bn_a", "pix_id": "bn_id", "budgets": "u_bounce_lspp",
             "sizes": "bn_m", "cuts": "lc_cut[{1}]", "leaves": "bn_leaf[{1}]", "pdfs": "bn_pdf[{1}]",
             "blocked": "lcb_blocked({1})"}


@functools.lru_cache(maxsize=None)
def _lightcuts(bounce: bool = False):
    """The lightcuts kernels of :mod:`renderers.lightcuts._kernels` and :mod:`~renderers.lightcuts.multires`
    translated, prefixed ``lc_`` (the translator and the functions in order): the counter-based random numbers
    ``lc_uniform(seed, pixel, slot)`` (splitmix64 in uint64 on 32-bit halves, the result in double precision, equal
    to the CPU's) and Algorithm 2's low-resolution pixel in double precision; in float32 the bounds of a node's box,
    the cut-refinement error, hierarchical importance sampling, the Lambertian estimate and the per-pixel bodies of
    the passes (``lc_cut_pixel``, ``lc_sample_pixel`` / ``lc_select_pixel``, ``lc_sort_pixel``,
    ``lc_shade_pixel``). The tree's arrays are the shader's tree image, the pixel arrays its storage buffers
    (``lc_buffers_gen.glsl``): pixel ``i`` of a tile is entry ``u_first + i``, its samples ``i * CUT_MAX + s``;
    with ``bounce``, the glossy bounce's one point instead (:data:`LC_BOUNCE`)."""
    from ..lightcuts import _kernels, multires

    tile, lr, ls = "smp[{0} * CUT_MAX + {1}].", "lr_ls[{0} * CUT_MAX + {1}].", "lr_ls[(u_first + {0}) * CUT_MAX + {1}]."
    tr = Translator(_kernels, "lc_", source=inspect.getsource(_kernels) + "\n" + inspect.getsource(multires),
                    bindings={"bmin": "node_min({0})[{1}]", "bmax": "node_max({0})[{1}]", "inten": "node_inten({0})",
                              "n_leaves": "u_n_leaves", "levels": "u_levels", "clamp2": "u_clamp2",
                              "light_pos": "light_pos({0})[{1}]", "light_rgb": "light_rgb({0})[{1}]",
                              "light_nrm": "light_nrm({0})[{1}]", "one_sided": "(u_one_sided != 0)",
                              "cut": "lc_cut[{0}]", "err": "lc_err[{0}]", "scale_x": "u_lr_scale.x",
                              "scale_y": "u_lr_scale.y", "lr_width": "u_lr_width", "lr_height": "u_lr_height",
                              "pos": "g_pos[u_first + {0}].xyz", "nrm": "g_nrm[u_first + {0}].xyz",
                              "albedo": "g_alb[u_first + {0}].xyz", "blocked": "lc_blocked({0}, {1})",
                              "pix_id": "uvec2(u_id_base + uint(u_first + {0}), 0u)",
                              "fmap": "intBitsToFloat(ctl[u_first + {0}].z)", "sizes": "pix[u_first + {0}].x",
                              # a cut's budget: 0 for an invalid pixel, else u_budget for all (>= 0) or ctl.x
                              "budgets": "(g_pos[u_first + {0}].w > 0.0 ? (u_budget >= 0 ? u_budget : "
                                         "ctl[u_first + {0}].x) : 0)",
                              "cuts": tile + "node", "leaves": tile + "leaf", "pdfs": tile + "pdf",
                              "lr_leaves": lr + "leaf", "lr_nodes": lr + "node", "lr_pdfs": lr + "pdf",
                              "lr_depths": lr + "depth", "lr_counts": "lr_pix[{0}].w", "ls_leaves": ls + "leaf",
                              "ls_nodes": ls + "node", "ls_pdfs": ls + "pdf", "ls_depths": ls + "depth",
                              **(LC_BOUNCE if bounce else {})})
    if bounce:   # the roots under their own names, their callees lightcuts_gen.glsl's
        tr.glsl_name = lambda name: ("lcb_" if name in LC_BOUNCE_ROOTS else "lc_") + name.lstrip("_")
    tr.binding_types.update({"pos": "vec3", "nrm": "vec3", "albedo": "vec3", "blocked": "bool", "pix_id": "u64",
                             **{k: "int" for k in ("n_leaves", "levels", "lr_width", "lr_height", "cut", "sizes",
                                                   "budgets", "cuts", "leaves", "lr_leaves", "lr_nodes", "lr_depths",
                                                   "lr_counts", "ls_leaves", "ls_nodes", "ls_depths")}})
    tr.float32_values["ONE_MINUS"] = LC_ONE_MINUS_F32   # the largest float32 below 1, as 1 - 2^-53 in float64
    # a parent's bound never below a leaf's cosine: the CPU's rounding of the sums
    tr.precise = {"box_terms", "dot_interval", "geom_bound", "sample_weight"}
    roots = (*_kernels.GLSL_FLOAT_ROOTS, *multires.GLSL_FLOAT_ROOTS)
    doubles, floats = tr.precision_closure((*_kernels.GLSL_DOUBLE_ROOTS, *multires.GLSL_DOUBLE_ROOTS), roots)
    point = {"p": "vec3", "n": "vec3", "t": "vec3", "b": "vec3", "k": "int", "node": "int", "j": "int",
             "one_sided": "bool", "budget": "int"}
    pixel = {"i": "int", "q": "int", "seed": "u64", "s0": "int", "s1": "int"}
    tr.infer(doubles + floats, {"uniform": {"seed": "u64", "pixel": "u64", "slot": "u64"},
                                "low_res_pixel": {"x": "int", "y": "int"},
                                **{r: point for r in _kernels.GLSL_FLOAT_ROOTS if "pixel" not in r},
                                **{r: pixel for r in roots if "pixel" in r}})
    return tr, doubles + floats


@functools.lru_cache(maxsize=None)
def glossy_glsl() -> str:
    """GLSL of the glossy pass's per-ray kernel of :mod:`renderers.lightcuts.glossy` (the lobe's direction and
    weight, seed 003 Algorithm 1 lines 16-17), float32, prefixed ``glossy_``; its constants (the random-number
    slot offset ``GLOSSY_STREAM``) with it."""
    from ..lightcuts import glossy

    tr = Translator(glossy, "glossy_")
    # the frame and the random numbers are lightcuts_gen.glsl's
    tr.externals = {"tangent": ("lc_tangent", "vec3"), "bitangent": ("lc_bitangent", "vec3"),
                    "uniform_f": ("lc_uniform_f", "float")}
    names = tr.closure(glossy.GLSL_FLOAT_ROOTS)
    tr.infer(names, {"lobe_sample": {"seed": "u64", "pix": "u64", "r": "int", "count": "int"}})
    return _header(glossy) \
        + tr.emit(names, helpers=False)


@functools.lru_cache(maxsize=None)
def fpsm_glsl() -> str:
    """GLSL of the FPSM's per-pixel kernels of :mod:`renderers.lightcuts.fpsm` (seed 003 Eq 1-8: the acuity, the
    Sobel gradient, the binomial blur, the B-spline resampling, the contrast, ρ, the map in float32; the budget in
    double precision like the CPU's float64), prefixed ``fpsm_``. The images they read are the shader's
    (``shaders/fpsm.comp``): ``img[c, k]`` is ``fp_img(c, k)``, ``gbuf[k, c]`` ``fp_gbuf(k, c)``, ``coef[k]``
    ``fp_low[k]``."""
    from ..lightcuts import fpsm

    tr = Translator(fpsm, "fpsm_", bindings={"img": "fp_img({0}, {1})", "gbuf": "fp_gbuf({0}, {1})",
                                             "coef": "fp_low[{0}]"})
    doubles, floats = tr.precision_closure(fpsm.GLSL_DOUBLE_ROOTS, fpsm.GLSL_FLOAT_ROOTS)
    ints = ("c", "x", "y", "w", "h", "at", "cw", "ch", "order", "channels", "reading", "most", "least")
    tr.infer(doubles + floats, {r: {p: "int" for p in tr.fns[r].params if p in ints}
                                for r in (*fpsm.GLSL_DOUBLE_ROOTS, *fpsm.GLSL_FLOAT_ROOTS)})
    return _header(fpsm) + '#include "constants_gen.glsl"\n' + tr.emit(doubles + floats, helpers=False)


@functools.lru_cache(maxsize=None)
def fxaa_glsl() -> str:
    """GLSL of FXAA's per-pixel kernel :func:`renderers.antialias.fxaa_pixel` (FXAA 3.11, quality preset 12),
    ``aa_fxaa_pixel(subpix, edge_threshold, edge_threshold_min, x, y)`` returning the pixel's colour, and its
    callees (``aa_bil``, ``aa_lu``). The CPU's image (colour and luma channels) is the shader's accessor
    ``aa_img(y, x, ch)`` and ``aa_dim(k)`` (fxaa.comp: the wrapped, padded LP buffer); the search steps
    ``FXAA_STEPS_12`` a constant array ``AA_STEPS``."""
    from .. import antialias

    steps = antialias.FXAA_STEPS_12
    tr = Translator(antialias, "aa_", bindings={"img": "aa_img({0}, {1}, {2})", "img.shape": "aa_dim({0})",
                                                "steps": "AA_STEPS[{0}]", "steps.size": str(len(steps))})
    tr.binding_types["img"] = "f32"
    # numba's types: float32 where the CPU adds image values, float64 elsewhere; no fused mul-add
    names, _ = tr.precision_closure(antialias.GLSL_DOUBLE_ROOTS)
    tr.precise = set(names)
    tr.infer(names, {"fxaa_pixel": {"x": "int", "y": "int"}})
    table = ", ".join(_flt(v) for v in steps)
    return (_header(antialias)
            + f"const float AA_STEPS[{len(steps)}] = float[{len(steps)}]({table});\n"
            + tr.emit(names, helpers=False))


@functools.lru_cache(maxsize=None)
def warp_glsl() -> str:
    """GLSL of the forward grid warping of :mod:`renderers._warp` (float32, prefixed ``rep_``): a quad of left
    samples ``rep_warp_quad(a, b, cc, d, w_eff, w, max_ratio, max_extent)`` (the depth-discontinuity test, the
    rasteriser of its two warped triangles), whose fragments go to the shader's own
    ``rep_fragment(idx, z, b0, b1, b2, ka, kb, kc)`` (rep_warp.comp); the LP columns' ``L[c]`` and ``n[c]`` are
    the shader's column table (lp_cols.glsl)."""
    from .. import _warp

    # the left samples' warped coordinates and depths are the shader's buffer warp (rep.glsl); the colours and the
    # depth buffer are the GPU fragment's own business (no binding text: never read by the generated code)
    tr = Translator(_warp, "rep_", bindings={"u": "warp[{0}].x", "phi": "warp[{0}].y", "z": "warp[{0}].z",
                                             "L": "cols({0}).w", "n": "int(cols({0}).z)", "col": "", "zbuf": "",
                                             "out": "", "covered": ""})
    tr.binding_types["n"] = "int"
    tr.externals = {"fragment": ("rep_fragment", "void")}
    names = tr.closure(_warp.GLSL_FLOAT_ROOTS)
    tr.infer(names, {"warp_quad": {k: "int" for k in ("a", "b", "cc", "d", "w_eff", "w")}})
    return _header(_warp) \
        + tr.emit(names, helpers=False)


@functools.lru_cache(maxsize=None)
def projection_glsl() -> str:
    """GLSL of the pinhole camera's formulas of :mod:`renderers.projection`, prefixed ``proj_``: a screen position's
    image-plane offsets ``proj_plane_offsets`` and its ray ``proj_ray_direction`` in double precision, ``precise``
    (camera.glsl: the CPU's float64 rays to the bit), and ``proj_plane_to_screen`` in float (the reprojection)."""
    from .. import projection

    tr = Translator(projection, "proj_")
    doubles, floats = tr.precision_closure(projection.GLSL_DOUBLE_ROOTS, projection.GLSL_FLOAT_ROOTS)
    tr.precise = set(doubles)
    tr.infer(doubles + floats, {r: {} for r in (*projection.GLSL_DOUBLE_ROOTS, *projection.GLSL_FLOAT_ROOTS)})
    return _header(projection) \
        + tr.emit(doubles + floats, helpers=False)


def _kernel_glsl(module, prefix: str, roots, params: dict, bindings: dict, binding_types: dict,
                 externals: dict | None = None, after=(), stores: dict | None = None) -> str:
    """GLSL of the closure of ``roots`` in ``module`` (``params``: the roots' parameter types), without the
    functions and constants of the closure of ``after``, emitted by another file the shader includes first."""
    tr = Translator(module, prefix, bindings=bindings)
    tr.binding_types.update(binding_types)
    tr.externals.update(externals or {})
    tr.stores.update(stores or {})
    done = tr.closure(after)
    names = [n for n in tr.closure(roots) if n not in done]
    tr.infer(done + names, params)
    head = _header(module)
    return head + tr.emit(names, helpers=False, consts=not after)


#: The LP kernels' arrays and scalars on the GPU: the LP buffer image ``src``, the per-column table ``cols``
#: (lp_cols.glsl), the u(r) table and the uniforms of lp_map.glsl; ``point`` is the generated ``fov_point``.
_LP_BINDINGS = {"lp": "imageLoad(src, ivec2({1}, {0}))[{2}]", "utab": "lp_utab({0})", "exact": "lp_exact({0})",
                "inv_step": "u_inv_step", "kmax": "u_kmax", "method": "METHOD", "gx": "u_gaze.x", "gy": "u_gaze.y",
                "Lr": "cols({0}).y", "n": "int(cols({0}).z)", "w_eff": "u_w_eff"}
_LP_INTS = dict.fromkeys(("exact", "kmax", "method", "n", "w_eff"), "int")


@functools.lru_cache(maxsize=None)
def lp_glsl(part: str = "u") -> str:
    """GLSL of the LP kernels of :mod:`renderers._lp`: ``part`` ``"u"`` the column of a screen offset
    (``lp_table_u(dx, dy)``, lp_map.glsl), ``"inverse"`` a screen pixel's colour (``lp_inverse_pixel(x, y)``,
    inverse_map.comp, which includes the first), ``"needed"`` whether an LP pixel is shaded (``lp_needed``,
    lp_mark.comp), ``"fill"`` the filling of an LP row (``lp_fill_row(j, w)``,
    in place in the image ``lp``; shaded: flag bit 1)."""
    from .. import _lp

    if part == "needed":   # double precision: the positions are the CPU's float64 (lp_cols.glsl lp_position_d)
        tr = Translator(_lp, "lp_")
        names = tr.closure(_lp.GLSL_NEEDED_ROOTS)
        tr.fns["needed"].real = "double"
        tr.infer(names, {"needed": {"border": "bool"}})
        return _header(_lp) \
            + tr.emit(names, helpers=False, consts=False)
    if part == "fill":
        return _kernel_glsl(_lp, "lp_", _lp.GLSL_FILL_ROOTS, {"fill_row": {"j": "int", "w": "int"}},
                            {"lp": "imageLoad(lp, ivec2({1}, {0}))",
                             "shaded": "((flags[({0}) * u_lp_w + ({1})] & 1u) != 0u)"},
                            {"lp": "vec4", "shaded": "bool"},
                            stores={"lp": "imageStore(lp, ivec2({1}, {0}), {value})"})
    roots = _lp.GLSL_FLOAT_ROOTS if part == "u" else _lp.GLSL_INVERSE_ROOTS
    return _kernel_glsl(_lp, "lp_", roots, {"table_u": {}, "inverse_pixel": {"x": "int", "y": "float"}},
                        _LP_BINDINGS, _LP_INTS, {"point": ("fov_point", "vec2")},
                        after=() if part == "u" else _lp.GLSL_FLOAT_ROOTS)


@functools.lru_cache(maxsize=None)
def antialias_glsl(part: str = "gauss") -> str:
    """GLSL of the Gaussians of :mod:`renderers.antialias`: ``part`` ``"gauss"`` a pixel's Gaussian
    (``aa_gauss_pixel``, gauss3.comp and foveal.comp), ``"foveal"`` the foveal band and pixel (foveal.comp, after
    the first), ``"luma"`` FXAA's luma (``aa_luma``, lp_luma.comp). The including shader defines ``px_at(y, x)``
    (the image) and the uniforms ``u_w`` (weights), ``u_edges`` and ``u_radii`` (the bands)."""
    from .. import antialias as AA

    if part == "luma":
        tr = Translator(AA, "aa_")
        names = tr.closure(AA.GLSL_LUMA_ROOTS)
        tr.infer(names, {"luma": {}})
        return _header(AA) \
            + tr.emit(names, helpers=False, consts=False)
    pixel = dict.fromkeys(("y", "x", "ch", "o", "r", "b", "h", "w"), "int")
    return _kernel_glsl(AA, "aa_", AA.GLSL_FLOAT_ROOTS if part == "gauss" else AA.GLSL_FOVEAL_ROOTS,
                        {"gauss_pixel": pixel, "foveal_pixel": pixel, "foveal_band": {}},
                        {"img": "px_at({0}, {1})[{2}]", "k": "u_w[{0}]", "edges": "u_edges[{0}]",
                         "radii": "u_radii[{0}]"}, {"radii": "int"},
                        after=() if part == "gauss" else AA.GLSL_FLOAT_ROOTS)


@functools.lru_cache(maxsize=None)
def gt_glsl() -> str:
    """GLSL of the GT kernels of :mod:`renderers._gt` in double precision, prefixed ``gt_``: the sample positions
    ``gt_sample_offset(px, py, s, spp, side)`` and the pixel filter ``gt_resolve_pixel(x, y, width, rows, spp,
    tent)`` (box or tent, numpy's summation order), which reads sample ``s`` of pixel ``(x, u_s0 + y)`` from the
    sample pipeline's output buffer ``outbuf`` (``samples.glsl``, rows of ``u_width`` pixels), its position from
    ``gt_sample_offset`` and keeps its 8 running sums in the shader's array ``gt_part``."""
    from .. import _gt

    offset = "gt_sample_offset({1}, u_s0 + ({0}), {2}, SPP, SPP_SIDE)"
    tr = Translator(_gt, "gt_", bindings={"rad": "outbuf[3 * ((({0}) * u_width + ({1})) * SPP + ({2})) + ({3})]",
                                          "ox": offset + ".x", "oy": offset + ".y", "part": "gt_part[{0}]"})
    names, _ = tr.precision_closure(_gt.GLSL_DOUBLE_ROOTS)
    tr.infer(names, {r: {p: "int" for p in tr.fns[r].params if p not in tr.bindings} for r in _gt.GLSL_DOUBLE_ROOTS})
    return _header(_gt) \
        + tr.emit(names, helpers=False)


def int64_glsl() -> str:
    """The 64-bit integer helpers of the generated kernels (``int64_gen.glsl``)."""
    return "// 64-bit integers on (lo, hi) halves for the generated kernels (renderers/gpu/codegen.py).\n" \
        + _I64_HELPERS


@functools.lru_cache(maxsize=None)
def constants_glsl() -> str:
    """Every constant of the shared table :mod:`renderers.constants` (upper-case ints and floats) as a GLSL
    ``const`` of the same name."""
    from .. import constants

    out = []
    for k, v in vars(constants).items():
        if k.isupper() and isinstance(v, (int, float)) and not isinstance(v, bool):
            out.append(f"const int {k} = {v};\n" if isinstance(v, int) else f"const float {k} = {_flt(v)};\n")
    return "".join(out)

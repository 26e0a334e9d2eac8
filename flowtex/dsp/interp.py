"""Texture-model interpolation: (speed, force) -> one ARMA model, every tick, allocation-free.

Per query (Culbertson et al. 2012, section 4.2, HaTT's renderer):

1. clamp speed and force HaTT's way (:func:`~flowtex.dsp.triangulation.clamp_query`);
2. locate the triangle and barycentric weights (:func:`~flowtex.dsp.triangulation.locate`);
3. blend the three models' AR LSFs, MA LSFs, excitation variance and MA gain
   with those weights (never raw coefficients: convex combinations of
   increasing LSF vectors stay increasing, so the model stays stable);
   with ``interpolation`` ``power`` or ``log_power`` the models' OUTPUT powers
   g^2 var ||C/A||^2 are blended instead (linearly, or geometrically over the
   non-silent vertices, scaled by their total weight so a silent corner still
   fades the power linearly), and the excitation variance is set so that the
   blended filter has that power: var = P / (g^2 ||C/A||^2), where
   g^2 ||C/A||^2 = sum v_m^2 over the ladder weights of the normalized
   lattice (:func:`~flowtex.dsp.arma.lattice_ladder_coefficients`): its states
   are orthonormal under white input, so the identity is exact and costs one
   O(L^2) step-down in caller-owned scratch, no allocation, no truncated
   impulse response;
4. convert the LSFs to A(z) and C(z) in float64 with
   :func:`~flowtex.dsp.lsf.lsf_to_poly`. The blend loop also checks the
   result is a valid LSF vector (as :func:`~flowtex.dsp.lsf.is_valid_lsf`
   with the table's ``min_gap``); only an invalid one (LSFs closer than
   ``min_gap``, rounding) goes through :func:`~flowtex.dsp.lsf.repair_lsf`.

Outside the measured models (``outside``, flowtex.models.outside): mode 0
(``fade``, HaTT's) blends the silent corner models (variance 0) like any other,
so the vibration fades out below the slowest fitted speed and the lightest
fitted force; mode 1 (``hold``) and mode 2 (``trend``) replace every silent
vertex by its nearest measured model (``src``), and ``trend`` then scales the
variance by (speed / s_eff)^ks (force / f_eff)^kf, where (s_eff, f_eff) is the
weighted point of the models actually blended and each ratio is capped at
``trend_cap``; only beyond the measured models (a clamped query, or a silent
vertex replaced): inside the measured models' triangles the three rules agree
exactly.

NaN in speed or force holds the last model (HaTT turns one NaN into NaN
output forever); before any valid query the held model is silence:
A = C = 1, gain 0, variance 0. A query equal to the previous one (after
clamping) reuses the previous result without recomputing it.

Everything is read from one packed float64 table (:func:`pack_texture_table`)
and kept in caller-owned state arrays sized by :func:`state_sizes`.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .arma import filter_power
from .layout import Field, Layout
from .lsf import DEFAULT_MIN_GAP, lsf_to_poly, repair_lsf
from .triangulation import clamp_query, locate, pack_triangulation

HEADER = Layout("float", [
    Field("p", 1, "AR order"),
    Field("q", 1, "MA order"),
    Field("nmod", 1, "number of models"),
    Field("off_tri", 1, "offset of the triangulation (flowtex.dsp.triangulation.pack_triangulation)"),
    Field("off_mod", 1, "offset of the models (MODEL rows)"),
    Field("max_speed", 1, "mm/s"),
    Field("max_force", 1, "N"),
    Field("speed_margin", 1, "mm/s"),
    Field("low_speed", 1, "mm/s"),
    Field("low_speed_value", 1, "mm/s"),
    Field("force_margin", 1, "N"),
    Field("low_force", 1, "N"),
    Field("low_force_value", 1, "N"),
    Field("min_gap", 1, "rad, for repair_lsf"),
    Field("outside", 1, "code of OUTSIDE_MODES"),
    Field("off_out", 1, "offset of the OUTSIDE section"),
    Field("interp", 1, "code of INTERP_MODES"),
])
"""The packed table's header; the triangulation, ``nmod`` MODEL rows and the OUTSIDE section follow at its offsets."""

MODEL = Layout("float", [
    Field("ar_lsf", "p", "AR line spectral frequencies"),
    Field("ma_lsf", "q", "MA line spectral frequencies"),
    Field("variance", 1, "excitation variance"),
    Field("gain", 1, "MA gain"),
    Field("power", 1, "output power g^2 var ||C/A||^2"),
], sizes=("p", "q"))
"""One model's row of the table (its width is ``p + q + M_EXTRA``)."""

OUTSIDE = Layout("float", [
    Field("ks", 1, "trend exponent in speed"),
    Field("kf", 1, "trend exponent in force"),
    Field("cap", 1, "trend_cap"),
    Field("src", "nmod", "per model, the measured model standing in for it"),
    Field("points", "2 * nmod", "per model, its (speed mm/s, force N)"),
], sizes=("nmod",))
"""The rule outside the measured models, at the header's ``off_out``."""

TABLE = Layout("float", [
    Field("header", HEADER.size()),
    Field("tri", "ntri", "the triangulation"),
    Field("models", f"nmod * (p + q + {MODEL.size(p=0, q=0)})", "the MODEL rows"),
    Field("outside", f"{OUTSIDE.size(nmod=0)} + 3 * nmod", "the OUTSIDE section"),
], sizes=("p", "q", "nmod", "ntri"))
"""The whole packed table for orders p, q, ``nmod`` models and a triangulation of ``ntri`` values."""

# Header slots: module-level ints from HEADER (numba compiles them as constants).
T_P = HEADER.const("p")
T_Q = HEADER.const("q")
T_NMOD = HEADER.const("nmod")
T_OFF_TRI = HEADER.const("off_tri")
T_OFF_MOD = HEADER.const("off_mod")
T_MAX_SPEED = HEADER.const("max_speed")
T_MAX_FORCE = HEADER.const("max_force")
T_SPEED_MARGIN = HEADER.const("speed_margin")
T_LOW_SPEED = HEADER.const("low_speed")
T_LOW_SPEED_VALUE = HEADER.const("low_speed_value")
T_FORCE_MARGIN = HEADER.const("force_margin")
T_LOW_FORCE = HEADER.const("low_force")
T_LOW_FORCE_VALUE = HEADER.const("low_force_value")
T_MIN_GAP = HEADER.const("min_gap")
T_OUTSIDE = HEADER.const("outside")
T_OFF_OUT = HEADER.const("off_out")
T_INTERP = HEADER.const("interp")
T_HEADER = HEADER.size()

O_KS = OUTSIDE.const("ks")
O_KF = OUTSIDE.const("kf")
O_CAP = OUTSIDE.const("cap")
O_SRC = OUTSIDE.const("src")

OUTSIDE_MODES = {"fade": 0, "hold": 1, "trend": 2}
"""Codes of the rules outside the measured models (flowtex.models.outside)."""
INTERP_MODES = {"variance": 0, "power": 1, "log_power": 2}
"""Codes of the interpolation rules: HaTT's (excitation variance blended), output power blended linearly, or geometrically."""
M_EXTRA = MODEL.size(p=0, q=0)
"""Per model, after its p AR and q MA LSFs: excitation variance, MA gain, output power."""

STATE = Layout("float", [
    Field("x", 1, "last query's speed (after clamping for fade), mm/s; NaN before any"),
    Field("y", 1, "last query's force, N; NaN before any"),
    Field("w", 3, "barycentric weights"),
    Field("var", 1, "held excitation variance"),
    Field("gain", 1, "held MA gain"),
    Field("ar", "p + 1", "held A(z)"),
    Field("ma", "q + 1", "held C(z)"),
    Field("lsf", "L", "scratch: the blended LSFs"),
    Field("lattice", "5 * L + 3", "scratch of filter_power"),
], sizes=("p", "q"), derived={"L": "max(p, q)"})
"""The lookup's float state for orders p, q."""

ISTATE = Layout("int", [
    Field("hint", 1, "triangle of the last query (-1: none), where locate starts"),
    Field("valid", 1, "1 once a query was answered"),
    Field("v", 3, "vertex (model) indices of the blend"),
])
"""The lookup's int state (fixed length)."""

S_X = STATE.const("x")
S_Y = STATE.const("y")
S_W = STATE.const("w")
S_VAR = STATE.const("var")
S_GAIN = STATE.const("gain")
S_AR = STATE.const("ar")

SI_HINT = ISTATE.const("hint")
SI_VALID = ISTATE.const("valid")
SI_V = ISTATE.const("v")
SI_SIZE = ISTATE.size()

_offsets = STATE.kernel_offsets()
"""(L, o_x, o_y, o_w, o_var, o_gain, o_ar, o_ma, o_lsf, o_lattice) for orders (p, q), generated from :data:`STATE`."""


def pack_texture_table(speeds: np.ndarray, forces: np.ndarray, triangles: np.ndarray, ar_lsf: np.ndarray, ma_lsf: np.ndarray,
                       variance: np.ndarray, gain: np.ndarray, max_speed: float, max_force: float,
                       speed_margin: float = 0.01, low_speed: float = 0.05, low_speed_value: float = 0.0001,
                       force_margin: float = 0.01, low_force: float = 0.05, low_force_value: float = 0.0001,
                       min_gap: float = DEFAULT_MIN_GAP, outside: str = "fade", src: np.ndarray | None = None,
                       trend: tuple[float, float] = (1.0, 1.0), trend_cap: float = 4.0,
                       interpolation: str = "variance") -> np.ndarray:
    """One float64 array holding the clamping rule, the triangulation and the models, for :func:`texture_lookup_block`.

    Units: speeds, margins and thresholds on speed in mm/s; forces in N. The
    clamping defaults are HaTT's: above the maximum -> maximum - 0.01,
    below 0.05 -> 0.0001. The hull projection measures distance in units of
    (max_speed, max_force). ``min_gap`` (rad) is passed to ``repair_lsf``.
    ``outside`` (a key of :data:`OUTSIDE_MODES`), ``src`` (per model, the
    measured model standing in for it; default itself), ``trend`` (ks, kf) and
    ``trend_cap``: the rule outside the measured models; ``interpolation`` (a
    key of :data:`INTERP_MODES`): how loudness is blended (module docstring).
    Defaults: HaTT's rule.
    """
    ar_lsf = np.ascontiguousarray(ar_lsf, dtype=np.float64)
    ma_lsf = np.ascontiguousarray(ma_lsf, dtype=np.float64)
    count, p = ar_lsf.shape
    q = ma_lsf.shape[1]
    tri_tab = pack_triangulation(speeds, forces, triangles, max_speed, max_force)
    variance = np.asarray(variance, np.float64)
    gain = np.asarray(gain, np.float64)
    models = np.column_stack([ar_lsf, ma_lsf, variance, gain, model_output_powers(ar_lsf, ma_lsf, variance, gain)])
    src = np.arange(count) if src is None else np.asarray(src)
    outside_part = OUTSIDE.pack({"ks": trend[0], "kf": trend[1], "cap": trend_cap, "src": src.astype(np.float64),
                                 "points": np.column_stack([np.asarray(speeds, np.float64), np.asarray(forces, np.float64)])},
                                nmod=count)
    at = TABLE.bind(p=p, q=q, nmod=count, ntri=tri_tab.size)
    head = HEADER.pack({"p": p, "q": q, "nmod": count, "off_tri": at["tri"].start, "off_mod": at["models"].start,
                        "max_speed": max_speed, "max_force": max_force, "speed_margin": speed_margin, "low_speed": low_speed,
                        "low_speed_value": low_speed_value, "force_margin": force_margin, "low_force": low_force,
                        "low_force_value": low_force_value, "min_gap": min_gap, "outside": OUTSIDE_MODES[outside],
                        "off_out": at["outside"].start, "interp": INTERP_MODES[interpolation]})
    return TABLE.pack({"header": head, "tri": tri_tab, "models": models, "outside": outside_part},
                      p=p, q=q, nmod=count, ntri=tri_tab.size)


def table_sizes(tab: np.ndarray) -> dict[str, int]:
    """The sizes (p, q, nmod, ntri) a packed table was laid out for (:data:`TABLE`), read from its header."""
    return {"p": int(tab[T_P]), "q": int(tab[T_Q]), "nmod": int(tab[T_NMOD]), "ntri": int(tab[T_OFF_MOD] - tab[T_OFF_TRI])}


class UnusableModel(ValueError):
    """A model whose LSFs give no stable filter in float64 (raised by :func:`model_output_powers`); ``model`` is its index."""

    def __init__(self, model: int) -> None:
        super().__init__(f"model {model}: its LSFs give no stable filter, so it has no output power")
        self.model = model


def model_output_powers(ar_lsf: np.ndarray, ma_lsf: np.ndarray, variance: np.ndarray, gain: np.ndarray) -> np.ndarray:
    """(M,) output power g^2 var ||C/A||^2 of each model, (m/s^2)^2, from its LSFs as the lookup renders them.

    Exact (the normalized lattice's sum of squared ladder weights,
    :func:`filter_power`); 0 for a silent model (variance 0). A model whose
    LSFs give no usable filter raises :class:`UnusableModel` (a ValueError).
    """
    ar_lsf = np.ascontiguousarray(ar_lsf, dtype=np.float64)
    ma_lsf = np.ascontiguousarray(ma_lsf, dtype=np.float64)
    count, p = ar_lsf.shape
    q = ma_lsf.shape[1]
    L = max(p, q)
    ar, ma = np.empty(p + 1), np.empty(q + 1)
    work = np.empty(5 * L + 3)
    out = np.zeros(count)
    for m in range(count):
        if variance[m] <= 0.0:
            continue
        lsf_to_poly(ar_lsf[m], ar)
        lsf_to_poly(ma_lsf[m], ma)
        unit = filter_power(ar, ma, float(gain[m]), work)
        if not unit >= 0.0:
            raise UnusableModel(m)
        out[m] = variance[m] * unit
    return out


def state_sizes(ar_order: int, ma_order: int) -> tuple[int, int]:
    """Lengths of the float and int state arrays for orders p, q."""
    return STATE.size(p=ar_order, q=ma_order), SI_SIZE


def initial_state(ar_order: int, ma_order: int) -> tuple[np.ndarray, np.ndarray]:
    """Fresh state: no query seen, held model silent (A = C = 1, gain 0, variance 0)."""
    at = STATE.bind(p=ar_order, q=ma_order)
    s = STATE.pack({"x": np.nan, "y": np.nan}, p=ar_order, q=ma_order)
    s[at["ar"].start] = 1.0
    s[at["ma"].start] = 1.0
    return s, ISTATE.pack({"hint": -1})


@njit(cache=True, inline="always")
def _blend_valid(models, width, col, n, v, w, min_gap, out):
    """Blend the three models' entries col..col+n-1 with weights ``w`` into ``out``; True if the result is a valid LSF vector.

    Valid exactly as :func:`~flowtex.dsp.lsf.is_valid_lsf` (``min_gap``):
    checked in the same pass, without branches, so the common case (a valid
    blend) needs no second loop; :func:`~flowtex.dsp.lsf.repair_lsf` runs only otherwise.
    """
    b0 = v[0] * width + col
    b1 = v[1] * width + col
    b2 = v[2] * width + col
    w0 = w[0]
    w1 = w[1]
    w2 = w[2]
    prev = 0.0
    ok = True
    for j in range(n):
        x = w0 * models[b0 + j] + w1 * models[b1 + j] + w2 * models[b2 + j]
        out[j] = x
        gap = x - prev
        ok &= (gap > 0.0) & (gap >= min_gap)  # False for NaN too
        prev = x
    last = math.pi - prev
    return ok & (last > 0.0) & (last >= min_gap)


@njit(cache=True, inline="always")
def _trend_factor(tab, o_out, v, w, speed, force):
    """(speed / s_eff)^ks (force / f_eff)^kf with each ratio in [0, cap]; (s_eff, f_eff) = weighted point of models ``v``."""
    nmod = int(tab[T_NMOD])
    o_pts = o_out + O_SRC + nmod
    se = w[0] * tab[o_pts + 2 * v[0]] + w[1] * tab[o_pts + 2 * v[1]] + w[2] * tab[o_pts + 2 * v[2]]
    fe = w[0] * tab[o_pts + 2 * v[0] + 1] + w[1] * tab[o_pts + 2 * v[1] + 1] + w[2] * tab[o_pts + 2 * v[2] + 1]
    cap = tab[o_out + O_CAP]
    rs = min(max(speed, 0.0) / se, cap) if se > 0.0 else 1.0
    rf = min(max(force, 0.0) / fe, cap) if fe > 0.0 else 1.0
    if rs <= 0.0 or rf <= 0.0:
        return 0.0  # at rest or without contact: silent for every exponent (0^0 would be 1)
    return rs ** tab[o_out + O_KS] * rf ** tab[o_out + O_KF]


@njit(cache=True, inline="always")
def _blend_power(models, width, v, w, log_mode):
    """Output power at the query: the vertices' powers blended linearly, or geometrically over the non-silent ones
    scaled by their total weight (a silent vertex then still fades the power linearly, as in HaTT's corners)."""
    b = width - 1
    if not log_mode:
        return w[0] * models[v[0] * width + b] + w[1] * models[v[1] * width + b] + w[2] * models[v[2] * width + b]
    total = 0.0
    acc = 0.0
    for k in range(3):
        pk = models[v[k] * width + b]
        if pk > 0.0 and w[k] > 0.0:
            total += w[k]
            acc += w[k] * math.log(pk)
    return total * math.exp(acc / total) if total > 0.0 else 0.0


@njit(cache=True)
def lookup_model(tab: np.ndarray, s: np.ndarray, si: np.ndarray, speed: float, force: float) -> None:
    """Update the held model in ``s`` for one (speed mm/s, force N) query (see the module docstring)."""
    if speed != speed or force != force:
        return  # NaN: hold
    p = int(tab[T_P])
    q = int(tab[T_Q])
    mode = int(tab[T_OUTSIDE])
    x = clamp_query(speed, tab[T_MAX_SPEED], tab[T_SPEED_MARGIN], tab[T_LOW_SPEED], tab[T_LOW_SPEED_VALUE])
    y = clamp_query(force, tab[T_MAX_FORCE], tab[T_FORCE_MARGIN], tab[T_LOW_FORCE], tab[T_LOW_FORCE_VALUE])
    kx = speed if mode != 0 else x  # hold, trend: the raw query decides rest and power, so two queries clamped alike differ
    ky = force if mode != 0 else y
    if kx == s[S_X] and ky == s[S_Y] and si[SI_VALID] != 0:
        return
    o_tri = int(tab[T_OFF_TRI])
    o_mod = int(tab[T_OFF_MOD])
    tri_tab = tab[o_tri:o_mod]
    models = tab[o_mod:]
    w = s[S_W:S_W + 3]
    v = si[SI_V:SI_V + 3]
    si[SI_HINT] = locate(tri_tab, x, y, si[SI_HINT], w, v)
    o_out = int(tab[T_OFF_OUT])
    beyond = x != speed or y != force  # clamped, or (below) blending a silent model: outside the measured models
    if mode != 0:
        o_src = o_out + O_SRC
        for k in range(3):
            m = int(tab[o_src + v[k]])
            beyond |= m != v[k]
            v[k] = m
    width = p + q + M_EXTRA
    L, _, _, _, _, _, o_ar, o_ma, o_lsf, o_lattice = _offsets(p, q)
    scratch = s[o_lsf:o_lsf + L]
    min_gap = tab[T_MIN_GAP]
    lsf = scratch[:p]
    if not _blend_valid(models, width, 0, p, v, w, min_gap, lsf):
        repair_lsf(lsf, min_gap)
    lsf_to_poly(lsf, s[o_ar:o_ar + p + 1])
    lsf = scratch[:q]
    if not _blend_valid(models, width, p, q, v, w, min_gap, lsf):
        repair_lsf(lsf, min_gap)
    lsf_to_poly(lsf, s[o_ma:o_ma + q + 1])
    b = p + q
    s[S_VAR] = w[0] * models[v[0] * width + b] + w[1] * models[v[1] * width + b] + w[2] * models[v[2] * width + b]
    b += 1
    s[S_GAIN] = w[0] * models[v[0] * width + b] + w[1] * models[v[1] * width + b] + w[2] * models[v[2] * width + b]
    interp = int(tab[T_INTERP])
    if interp != 0:
        target = _blend_power(models, width, v, w, interp == 2)
        unit = filter_power(s[o_ar:o_ar + p + 1], s[o_ma:o_ma + q + 1], s[S_GAIN], s[o_lattice:o_lattice + 5 * L + 3])
        s[S_VAR] = target / unit if unit > 0.0 and target > 0.0 else 0.0
    if mode == 2 and beyond:
        s[S_VAR] *= _trend_factor(tab, o_out, v, w, speed, force)
    if mode != 0 and (not speed > 0.0 or speed < tab[T_LOW_SPEED] or not force > 0.0 or force < tab[T_LOW_FORCE]):
        s[S_VAR] = 0.0  # hold, trend: at rest or without contact, silent
    s[S_X] = kx
    s[S_Y] = ky
    si[SI_VALID] = 1


@njit(cache=True)
def texture_lookup_block(tab: np.ndarray, s: np.ndarray, si: np.ndarray, speed: np.ndarray, force: np.ndarray,
                         ar: np.ndarray, ma: np.ndarray, gain: np.ndarray, variance: np.ndarray) -> None:
    """Run :func:`lookup_model` for each row of ``speed``/``force`` (n, 1) and write the model to the (n, width) outputs."""
    p = int(tab[T_P])
    q = int(tab[T_Q])
    _, _, _, _, _, _, o_ar, o_ma, _, _ = _offsets(p, q)
    for t in range(speed.shape[0]):
        lookup_model(tab, s, si, speed[t, 0], force[t, 0])
        for j in range(p + 1):
            ar[t, j] = s[o_ar + j]
        for j in range(q + 1):
            ma[t, j] = s[o_ma + j]
        gain[t, 0] = s[S_GAIN]
        variance[t, 0] = s[S_VAR]

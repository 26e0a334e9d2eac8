"""Friction kernels: HaTT's Coulomb/viscous rule and Dahl stick-slip.

Sources: Kuchenbecker & Culbertson 2014, "Haptic rendering of textures" (tutorial) (HaTT's rule);
Culbertson & Kuchenbecker 2017, "Importance of matching physical friction, hardness, and texture
in creating realistic haptic virtual surfaces" (Dahl model, section 3.3.1).

Units: velocity mm/s, position mm, normal force N, friction force N. Forces
are 3-vectors in the tangent plane; docs/friction.md derives the choices.

Common conventions
* A negative normal force is treated as 0 (no contact, no friction).
* A non-finite normal force or velocity/position gives zero friction for that
  tick; the Dahl state is then left untouched, so the next valid sample
  continues from the last valid one (no NaN is ever stored). Finite inputs so
  large that squaring them overflows (|x| > ~1e154) are treated the same way.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .layout import Field, Layout
from .motion import finite3, update_normal

VISCOUS_PER_MM_S = 0.004
"""HaTT's viscous factor: F = -mu F_n 0.004 v with v in mm/s."""

# ---- Coulomb / viscous layout ----------------------------------------------
COULOMB_P = Layout("float", [Field("mu", 1, "kinetic friction coefficient"),
                             Field("threshold", 1, "speed from which the force is Coulomb's, mm/s")])
CF_MU = COULOMB_P.const("mu")
CF_THRESHOLD = COULOMB_P.const("threshold")
COULOMB_PARAMS = COULOMB_P.size()


def coulomb_threshold(mu: float, mode: str) -> float:
    """Speed (mm/s) at which the rule switches from viscous to Coulomb.

    ``hatt``: mu / 0.004 (HaTT's rule; the force jumps from mu^2 F_n to mu F_n
    there). ``continuous``: 1 / 0.004 = 250 mm/s, where the viscous line
    mu F_n 0.004 v meets mu F_n, so the force is continuous in v.
    """
    if mode == "hatt":
        return mu / VISCOUS_PER_MM_S
    if mode == "continuous":
        return 1.0 / VISCOUS_PER_MM_S
    raise ValueError(f"unknown friction mode {mode!r}; use continuous or hatt")


@njit(cache=True)
def coulomb_block(p: np.ndarray, vel: np.ndarray, fn: np.ndarray, out: np.ndarray) -> None:
    """Viscous below the threshold speed, Coulomb above, always opposing the velocity.

    |v| < v_th: F = -mu F_n 0.004 v;  |v| >= v_th: F = -mu F_n v/|v|.
    """
    mu = p[CF_MU]
    vth = p[CF_THRESHOLD]
    for t in range(vel.shape[0]):
        f = fn[t, 0]
        if not (finite3(vel, t) and math.isfinite(f)) or f <= 0.0:
            out[t, 0] = 0.0
            out[t, 1] = 0.0
            out[t, 2] = 0.0
            continue
        v0 = vel[t, 0]
        v1 = vel[t, 1]
        v2 = vel[t, 2]
        speed = math.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
        if not math.isfinite(speed * f):  # overflowing velocity: no direction to oppose
            out[t, 0] = 0.0
            out[t, 1] = 0.0
            out[t, 2] = 0.0
            continue
        if speed < vth or speed == 0.0:  # at rest: no direction (and mu = 0 in hatt mode gives vth = 0)
            k = -mu * f * VISCOUS_PER_MM_S
        else:
            k = -mu * f / speed
        out[t, 0] = k * v0
        out[t, 1] = k * v1
        out[t, 2] = k * v2


# ---- Dahl layout ---------------------------------------------------------------
DAHL_P = Layout("float", [Field("mu", 1, "kinetic friction coefficient"), Field("z_max", 1, "largest stretch, mm")])
DAHL_S = Layout("float", [
    Field("w", 3, "adhesion point, mm"),
    Field("xprev", 3, "last valid tool position, mm"),
    Field("normal", 3, "last valid unit normal"),
    Field("fn", 1, "normal force of the last valid tick, N (>= 0)"),
])
DAHL_SI = Layout("int", [Field("started", 1, "1 once a valid tick was seen")])
DP_MU = DAHL_P.const("mu")
DP_ZMAX = DAHL_P.const("z_max")
DAHL_PARAMS = DAHL_P.size()
DS_W = DAHL_S.const("w")
DS_XPREV = DAHL_S.const("xprev")
DS_NORMAL = DAHL_S.const("normal")
DS_FN = DAHL_S.const("fn")
DAHL_STATE = DAHL_S.size()
DI_STARTED = DAHL_SI.const("started")
DAHL_ISTATE = DAHL_SI.size()


@njit(cache=True)
def dahl_block(p: np.ndarray, s: np.ndarray, si: np.ndarray, pos: np.ndarray, fn: np.ndarray, nrm: np.ndarray,
               out: np.ndarray) -> None:
    """Dahl stick-slip friction in the tangent plane, energy-limited under a varying normal force.

    Per valid tick i (P = I - n n^T projects onto the tangent plane):

    1. If F_n rose (F_n,i > F_n,i-1 > ... ), shrink the spring so its stored
       energy mu F_n |z|^2 / (2 z_max) does not grow: w moves towards x_{i-1}
       by the factor sqrt(F_n,i-1 / F_n,i) (to x_{i-1} itself after lift-off).
    2. z = P (x_i - w_{i-1}); if |z| > z_max: z <- z z_max / |z| and
       w_i = x_i - z (the adhesion point is dragged along), else w_i = w_{i-1}.
       On a straight path this is exactly Culbertson & Kuchenbecker 2017, eq. (1).
    3. F = -mu F_n z / z_max (Culbertson & Kuchenbecker 2017, eq. (2), opposing the stretch).

    The first valid tick places w at the tool (F = 0).
    """
    mu = p[DP_MU]
    zmax = p[DP_ZMAX]
    for t in range(pos.shape[0]):
        update_normal(nrm, t, s, DS_NORMAL)
        f = fn[t, 0]
        if not (finite3(pos, t) and math.isfinite(f)):
            out[t, 0] = 0.0
            out[t, 1] = 0.0
            out[t, 2] = 0.0
            continue
        if f < 0.0:
            f = 0.0
        if si[DI_STARTED] == 0:
            si[DI_STARTED] = 1
            for c in range(3):
                s[DS_W + c] = pos[t, c]
                s[DS_XPREV + c] = pos[t, c]
            s[DS_FN] = f
        q0 = pos[t, 0] - s[DS_W]
        q1 = pos[t, 1] - s[DS_W + 1]
        q2 = pos[t, 2] - s[DS_W + 2]
        if not math.isfinite(q0 * q0 + q1 * q1 + q2 * q2 + f * f):  # overflowing jump: treat as invalid
            out[t, 0] = 0.0
            out[t, 1] = 0.0
            out[t, 2] = 0.0
            continue
        fprev = s[DS_FN]
        if f > fprev:
            shrink = math.sqrt(fprev / f)
            for c in range(3):
                xp = s[DS_XPREV + c]
                s[DS_W + c] = xp - shrink * (xp - s[DS_W + c])
        s[DS_FN] = f
        n0 = s[DS_NORMAL]
        n1 = s[DS_NORMAL + 1]
        n2 = s[DS_NORMAL + 2]
        r0 = pos[t, 0] - s[DS_W]
        r1 = pos[t, 1] - s[DS_W + 1]
        r2 = pos[t, 2] - s[DS_W + 2]
        rn = r0 * n0 + r1 * n1 + r2 * n2
        z0 = r0 - rn * n0
        z1 = r1 - rn * n1
        z2 = r2 - rn * n2
        length = math.sqrt(z0 * z0 + z1 * z1 + z2 * z2)
        if length > zmax:
            k = zmax / length
            z0 *= k
            z1 *= k
            z2 *= k
            s[DS_W] = pos[t, 0] - z0
            s[DS_W + 1] = pos[t, 1] - z1
            s[DS_W + 2] = pos[t, 2] - z2
        for c in range(3):
            s[DS_XPREV + c] = pos[t, c]
        g = -mu * f / zmax
        out[t, 0] = g * z0
        out[t, 1] = g * z1
        out[t, 2] = g * z2

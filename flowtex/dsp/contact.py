"""Contact and speed constants of HaTT and of the papers flowtex follows, in one place.

The contact node, the fits (friction, texture, taps), the scene planner and
the speed estimator all read them from here, so "in contact" and "the
rendering speed" mean the same thing everywhere.
"""

from __future__ import annotations

CONTACT_ON_N = 0.1
"""Normal force (N) at or above which contact begins (the contact node's ``on_n``; the fits' in-contact floor)."""
CONTACT_OFF_N = 0.05
"""Normal force (N) below which contact ends (the contact node's ``off_n``; hysteresis below :data:`CONTACT_ON_N`)."""

HATT_CORNER_RAD_S = 125.0
"""HaTT's speed filter corner (Penn Haptic Texture Toolkit renderer): 2nd-order Butterworth, rad/s."""
DEFAULT_CUTOFF_HZ = 20.0
"""Rendering speed filter of Kuchenbecker & Culbertson 2014 and Romano & Kuchenbecker 2012 (first-order low-pass), Hz."""
STATIONARY_MM = 0.06
"""Filtered displacement (mm) below which the speed estimator reports rest (Romano & Kuchenbecker 2012)."""

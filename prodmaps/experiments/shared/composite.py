"""What Figures 7 and 9 share: the composite function of the paper's cat, on a human.

The composite function is the human stand-in for the paper's cat (indicator on the left leg, a
Gaussian at the top of the right leg, a sine on the tail, an increasing function on the ears). It
is defined on the source shape only, from anchor vertices found by coordinates (z up, the body
faces -y, so the person's *left* is +x) and heat-method geodesic distances, lengths in metres on
a ~1.7 m body:

=========== ===================================================================== ===========================
part        region                                                                values
=========== ===================================================================== ===========================
indicator   left lower leg: geodesic distance to the left foot tip < 0.45          1
Gaussian    centre: the frontmost vertex on the right leg at distance 0.75 ± 0.02  exp(-d²/(2·0.07²))
            from the right foot tip (top of the thigh)
sine        left arm: distance to the left hand tip (max x) < 0.55                 sin(2π x / 0.12)
increasing  head: distance to the top of the head (max z) < 0.22                    (z - z_low)/(z_high - z_low)
=========== ===================================================================== ===========================

The parts do not overlap; everything else is 0; values in [-1, 1].

Conventions: ``C_12 = Φ2ᵀ A2 Φ1[p2p_21]`` ``(k_N + 1, k_M + 1)``; ``k_M``, ``k_N`` are the paper's
counts (non-constant functions); the reference on the target is the pull-back ``f[p2p_21]``.
"""

from __future__ import annotations

import numpy as np

__all__ = ["composite_function"]


def composite_function(mesh):
    """The composite test function ``(n,)`` on ``mesh``, its parts and its anchor vertices (module doc)."""
    from ...geodesics import distances

    V = mesh.vertices
    x, y, z = V.T
    left, right = np.flatnonzero(x > 0), np.flatnonzero(x < 0)
    foot_l = left[np.argmin(z[left])]  # lowest vertex of the left leg
    foot_r = right[np.argmin(z[right])]
    hand_l = int(np.argmax(x))  # tip of the left hand
    head_top = int(np.argmax(z))
    d_fl, d_fr, d_hl, d_top = distances(mesh, np.array([foot_l, foot_r, hand_l, head_top]))
    cand = np.flatnonzero(np.abs(d_fr - 0.75) < 0.02)  # ring around the right thigh
    centre = int(cand[np.argmin(y[cand])])  # its frontmost vertex
    d_c = distances(mesh, np.array([centre]))[0]
    indicator = (d_fl < 0.45).astype(float)
    gaussian = np.exp(-d_c**2 / (2 * 0.07**2))
    sine = np.where(d_hl < 0.55, np.sin(2 * np.pi * x / 0.12), 0.0)
    head = d_top < 0.22
    zh = z[head]
    ramp = np.where(head, (z - zh.min()) / (zh.max() - zh.min()), 0.0)
    parts = {"indicator": indicator, "gaussian": gaussian, "sine": sine, "increasing": ramp}
    anchors = {"foot_left": int(foot_l), "foot_right": int(foot_r), "hand_left": hand_l,
               "head_top": head_top, "gaussian_centre": centre}
    return indicator + gaussian + sine + ramp, parts, anchors

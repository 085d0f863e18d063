"""Real spherical harmonics up to degree 3, as the INRIA 3DGS code evaluates them.

The GLSL twin is ``glsl/sh.glsl``; both follow section 2 of the maths page.
"""

from __future__ import annotations

import numpy as np

C0 = 0.28209479177387814
C1 = 0.4886025119029199
C2 = (1.0925484305920792, -1.0925484305920792, 0.31539156525252005, -1.0925484305920792, 0.5462742152960396)
C3 = (-0.5900435899266435, 2.890611442640554, -0.4570457994644658, 0.3731763325901154,
      -0.4570457994644658, 1.445305721320277, -0.5900435899266435)


def sh_basis(directions: np.ndarray, degree: int) -> np.ndarray:
    """(N, 3) unit directions -> (N, (degree+1)^2) basis values, in the directions' dtype."""
    x, y, z = directions[:, 0], directions[:, 1], directions[:, 2]
    terms = [np.full_like(x, C0)]
    if degree >= 1:
        terms += [-C1 * y, C1 * z, -C1 * x]
    if degree >= 2:
        xx, yy, zz = x * x, y * y, z * z
        terms += [C2[0] * x * y, C2[1] * y * z, C2[2] * (2 * zz - xx - yy), C2[3] * x * z, C2[4] * (xx - yy)]
    if degree >= 3:
        terms += [
            C3[0] * y * (3 * xx - yy),
            C3[1] * x * y * z,
            C3[2] * y * (4 * zz - xx - yy),
            C3[3] * z * (2 * zz - 3 * xx - 3 * yy),
            C3[4] * x * (4 * zz - xx - yy),
            C3[5] * z * (xx - yy),
            C3[6] * x * (xx - 3 * yy),
        ]
    return np.stack(terms, axis=1)


def sh_to_rgb(sh: np.ndarray, degree: int, directions: np.ndarray) -> np.ndarray:
    """Colour max(SH(dir) + 0.5, 0) for (N, K, 3) coefficients and (N, 3) unit directions."""
    basis = sh_basis(directions, degree)
    return np.maximum(np.einsum("nk,nkc->nc", basis, sh[:, : basis.shape[1]]) + 0.5, 0.0)

"""A thin OSQP solver for the SQP's subproblems: OSQP's compiled solver without its Python
wrapper's per-call work.

``osqp.OSQP`` checks and converts its matrices on every ``setup`` (``tril``/``triu`` copies,
index-type checks), then factorises the KKT system twice when ``rho`` is given (once in
the constructor, once more in ``update_rho``); ``update_settings`` walks every setting. On
the SQP's problems (about 360 variables, 540 rows, 2,900 nonzeros) that is half of each
set-up: 457 → 228 µs measured on 37 recorded shelf_boxes subproblems, the same solutions to
the bit. The QP here always hands over upper-triangular P and column-sorted CSC matrices.

The compiled module's names (``OSQPSolver``, ``CSC``, ``OSQPSettings``) are OSQP 1.x's
bindings, not its documented API: when they are missing, the public ``osqp.OSQP`` serves
(the same solver, slower set-ups). ``tests/test_trajopt.py`` checks both give the same
solution.
"""

from __future__ import annotations

import importlib
from types import ModuleType
from typing import Any

import numpy as np
import osqp
import scipy.sparse as sp
from numpy.typing import NDArray

Array = NDArray[np.float64]


def _builtin_extension() -> ModuleType | None:
    """OSQP's compiled builtin-algebra module when it has the names used here, else None."""
    try:
        ext = importlib.import_module("osqp.ext_builtin")
    except ImportError:
        return None
    names = ("OSQPSolver", "CSC", "OSQPSettings", "osqp_set_default_settings", "OSQP_INFTY")
    return ext if all(hasattr(ext, n) for n in names) else None


_EXT = _builtin_extension()


class QPSolver:
    """OSQP on min ½ xᵀPx + qᵀx s.t. l ≤ Ax ≤ u, set up once and then updated in place.

    ``P``: upper triangle, CSC; ``A``: CSC with sorted row indices. ``settings``: OSQP's
    (``eps_abs``, ``rho``, ``max_iter``, …). ``direct`` False forces the public wrapper.
    """

    def __init__(self, P: sp.csc_matrix, q: Array, A: sp.csc_matrix, lower: Array,
                 upper: Array, settings: dict[str, Any], *, direct: bool = True) -> None:
        self._ext = _EXT if direct else None
        if self._ext is None:
            self._public: osqp.OSQP | None = osqp.OSQP(algebra="builtin")
            self._public.setup(P, q, A, lower, upper, **settings)
            return
        self._public = None
        ext = self._ext
        self._inf = float(ext.OSQP_INFTY)
        self._settings = ext.OSQPSettings()
        ext.osqp_set_default_settings(self._settings)
        for name, value in settings.items():
            setattr(self._settings, name, value)
        m, n = A.shape
        self._solver = ext.OSQPSolver(ext.CSC(P), q, ext.CSC(A), self._clip_lower(lower),
                                      self._clip_upper(upper), m, n, self._settings)

    def _clip_lower(self, lower: Array) -> Array:
        return np.maximum(lower, -self._inf)

    def _clip_upper(self, upper: Array) -> Array:
        return np.minimum(upper, self._inf)

    def update(self, *, q: Array, lower: Array, upper: Array, Ax: Array | None = None
               ) -> None:
        """New q, bounds and (when given) A's values in its pattern's order; a new A is
        factorised anew."""
        if self._public is not None:
            if Ax is None:
                self._public.update(q=q, l=lower, u=upper)
            else:
                self._public.update(Ax=Ax, q=q, l=lower, u=upper)
            return
        self._solver.update_data_vec(q=q, l=self._clip_lower(lower), u=self._clip_upper(upper))
        if Ax is not None:
            self._solver.update_data_mat(P_x=None, P_i=None, A_x=Ax, A_i=None)

    def warm_start(self, x: Array) -> None:
        """ADMM's next start at x (its duals as the last solve left them)."""
        if self._public is not None:
            self._public.warm_start(x=x)
        else:
            self._solver.warm_start(x, None)

    def solve(self, time_limit_s: float) -> tuple[Array | None, int, str]:
        """(x or None, ADMM iterations, OSQP's status text), within ``time_limit_s`` s."""
        if self._public is not None:
            self._public.update_settings(time_limit=time_limit_s)
            res = self._public.solve(raise_error=False)
            return res.x, int(res.info.iter), str(res.info.status)
        self._settings.time_limit = time_limit_s
        self._solver.update_settings(self._settings)
        self._solver.solve()
        info = self._solver.info
        return self._solver.solution.x, int(info.iter), str(info.status)

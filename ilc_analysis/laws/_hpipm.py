r"""HPIPM's optimal-control QP solver through its C API (the library in the casadi wheel).

HPIPM (Frison and Diehl, 2020) solves the stage-wise QP

.. math::

    \min \sum_{k=0}^{K} \tfrac12 \begin{bmatrix} u_k \\ x_k \end{bmatrix}^\top
    \begin{bmatrix} R_k & S_k \\ S_k^\top & Q_k \end{bmatrix}
    \begin{bmatrix} u_k \\ x_k \end{bmatrix} + r_k^\top u_k + q_k^\top x_k
    \quad\text{s.t.}\quad
    x_{k+1} = A_k x_k + B_k u_k + b_k,\quad
    \underline{b}_k \le (u_k, x_k)_{\text{bounded}} \le \overline{b}_k,\quad
    \underline{g}_k \le C_k x_k + D_k u_k \le \overline{g}_k

by a primal-dual interior-point method whose Newton steps are Riccati recursions: the work per
iteration is :math:`O(K(n_x + n_u)^3)`, linear in the number of stages. CasADi's ``conic``
interface to the same library re-derives the stage blocks from the global sparsity at set-up
and at every call (quadratic in K at K = 2 000); here the stage data are handed over directly:
each field is one flat buffer and an array of per-stage pointers into it (built once), and one
call of ``d_ocp_qp_set_all_rowmaj`` loads a problem. Bounds that are infinite are switched off
by HPIPM's masks, not replaced by large numbers.

The library and its headers ship in the casadi wheel (``casadi/libhpipm.so``,
``casadi/include/hpipm_*.h``); the structures are allocated from their ``*_strsize`` and
``*_memsize`` functions, so no C layout is assumed here; the one signature that differs between
HPIPM releases (the slack arguments of ``d_ocp_qp_set_all_rowmaj``) is read from the header.
"""

from __future__ import annotations

import ctypes
from dataclasses import dataclass
from pathlib import Path

import casadi as ca
import numpy as np

from ..exceptions import ParameterError

__all__ = ["HpipmOcpQp", "HpipmResult", "HPIPM_STATUS", "hpipm_library"]

#: HPIPM's return flags (``enum hpipm_status``)
HPIPM_STATUS = {0: "success", 1: "maximum number of iterations reached",
                2: "minimum step length reached", 3: "NaN in the computation",
                4: "inconsistent equality constraints"}

#: ``enum hpipm_mode``
_MODES = {"speed_abs": 0, "speed": 1, "balance": 2, "robust": 3}

_FIELDS = ("A", "B", "b", "Q", "S", "R", "q", "r", "idxbx", "lbx", "ubx", "idxbu", "lbu",
           "ubu", "C", "D", "lg", "ug")
_SOLUTION = ("u", "x", "pi", "lam_lb", "lam_ub", "lam_lg", "lam_ug")

_library: ctypes.CDLL | None = None
_set_all_has_idxs_rev = False   # whether this HPIPM's d_ocp_qp_set_all_rowmaj takes idxs_rev


def hpipm_library() -> ctypes.CDLL:
    """The HPIPM shared library of the casadi wheel, loaded once (with its BLASFEO)."""
    global _library, _set_all_has_idxs_rev
    if _library is None:
        root = Path(ca.__file__).parent
        candidates = sorted(root.glob("libhpipm.so*")) + sorted(root.glob("libhpipm.dylib"))
        if not candidates:
            raise ParameterError(f"HPIPM is not in this casadi installation ({root}): use the "
                                 f"stage form with solver='osqp'")
        for dep in sorted(root.glob("libblasfeo.so*")):
            ctypes.CDLL(str(dep), mode=ctypes.RTLD_GLOBAL)
            break
        lib = ctypes.CDLL(str(candidates[0]))
        size = ctypes.c_size_t
        vp = ctypes.c_void_p
        for name in ("d_ocp_qp_dim_strsize", "d_ocp_qp_strsize", "d_ocp_qp_sol_strsize",
                     "d_ocp_qp_ipm_arg_strsize", "d_ocp_qp_ipm_ws_strsize"):
            getattr(lib, name).restype = size
            getattr(lib, name).argtypes = []
        lib.d_ocp_qp_dim_memsize.restype = size
        lib.d_ocp_qp_dim_memsize.argtypes = [ctypes.c_int]
        for name in ("d_ocp_qp_memsize", "d_ocp_qp_sol_memsize", "d_ocp_qp_ipm_arg_memsize"):
            getattr(lib, name).restype = size
            getattr(lib, name).argtypes = [vp]
        lib.d_ocp_qp_ipm_ws_memsize.restype = size
        lib.d_ocp_qp_ipm_ws_memsize.argtypes = [vp, vp]
        # HPIPM releases differ in d_ocp_qp_set_all_rowmaj's slack arguments (idxs_rev was
        # added): read the signature from the header shipped beside the library
        header = root / "include" / "hpipm_d_ocp_qp.h"
        text = header.read_text() if header.is_file() else ""
        start = text.find("void d_ocp_qp_set_all_rowmaj(")
        if start < 0:
            raise ParameterError(f"the HPIPM header of this casadi installation ({header}) does "
                                 f"not declare d_ocp_qp_set_all_rowmaj: use solver='osqp'")
        _set_all_has_idxs_rev = "idxs_rev" in text[start:text.find(";", start)]
        _library = lib
    return _library


@dataclass(frozen=True)
class HpipmResult:
    """One solve: HPIPM's flag and its meaning, iterations, the largest residuals of the KKT
    conditions at the returned point (stationarity, equality, inequality, complementarity),
    (the solution itself is in :attr:`HpipmOcpQp.solution`)."""

    status: int
    status_text: str
    iterations: int
    residuals: dict

    @property
    def success(self) -> bool:
        return self.status == 0


class HpipmOcpQp:
    """An HPIPM OCP QP of fixed dimensions (allocated once) solved for new data each call.

    Parameters
    ----------
    nx, nu, nbx, nbu, ng : sequence of int, length K + 1
        Per stage: states, controls, bounded states, bounded controls, general constraints
        (stage K has no dynamics after it).
    tolerance : float
        HPIPM's tolerances on the stationarity, equality, inequality and complementarity
        residuals.
    iter_max : int
        Iteration limit.
    mode : {"robust", "balance", "speed", "speed_abs"}
        HPIPM's preset (default ``"robust"``).

    Attributes
    ----------
    data : dict of ndarray
        One flat buffer per field of :data:`_FIELDS`; :meth:`view` gives a stage's block.
    """

    def __init__(self, nx, nu, nbx, nbu, ng, *, tolerance: float, iter_max: int = 200,
                 mode: str = "robust") -> None:
        lib = hpipm_library()
        self.K = len(nx) - 1
        dims = {name: np.ascontiguousarray(v, dtype=np.intc)
                for name, v in (("nx", nx), ("nu", nu), ("nbx", nbx), ("nbu", nbu),
                                ("ng", ng))}
        if any(v.shape != (self.K + 1,) for v in dims.values()):
            raise ParameterError("nx, nu, nbx, nbu and ng must have one entry per stage")
        self.dims = dims
        self._ns = np.zeros(self.K + 1, dtype=np.intc)
        self._keep: list = []            # buffers HPIPM points into: alive as long as self
        self.dim = self._struct(lib.d_ocp_qp_dim_strsize())
        mem = self._memory(lib.d_ocp_qp_dim_memsize(self.K))
        lib.d_ocp_qp_dim_create(ctypes.c_int(self.K), self.dim, mem)
        lib.d_ocp_qp_dim_set_all(*(self._ptr(dims[n]) for n in ("nx", "nu", "nbx", "nbu", "ng")),
                                 self._ptr(self._ns), self.dim)
        self.qp = self._struct(lib.d_ocp_qp_strsize())
        lib.d_ocp_qp_create(self.dim, self.qp, self._memory(lib.d_ocp_qp_memsize(self.dim)))
        self.sol = self._struct(lib.d_ocp_qp_sol_strsize())
        lib.d_ocp_qp_sol_create(self.dim, self.sol,
                                self._memory(lib.d_ocp_qp_sol_memsize(self.dim)))
        self.arg = self._struct(lib.d_ocp_qp_ipm_arg_strsize())
        lib.d_ocp_qp_ipm_arg_create(self.dim, self.arg,
                                    self._memory(lib.d_ocp_qp_ipm_arg_memsize(self.dim)))
        lib.d_ocp_qp_ipm_arg_set_default(ctypes.c_int(_MODES[mode]), self.arg)
        tol = ctypes.c_double(tolerance)
        for name in ("stat", "eq", "ineq", "comp"):
            getattr(lib, f"d_ocp_qp_ipm_arg_set_tol_{name}")(ctypes.byref(tol), self.arg)
        it = ctypes.c_int(iter_max)
        lib.d_ocp_qp_ipm_arg_set_iter_max(ctypes.byref(it), self.arg)
        self.ws = self._struct(lib.d_ocp_qp_ipm_ws_strsize())
        lib.d_ocp_qp_ipm_ws_create(self.dim, self.arg, self.ws,
                                   self._memory(lib.d_ocp_qp_ipm_ws_memsize(self.dim, self.arg)))
        # the data: one flat buffer per field, per-stage offsets
        n_x, n_u, n_bx, n_bu, n_g = (dims[n] for n in ("nx", "nu", "nbx", "nbu", "ng"))
        nxn = np.append(n_x[1:], 0)                # states of the next stage (none after K)
        sizes = {"A": nxn * n_x, "B": nxn * n_u, "b": nxn, "Q": n_x * n_x, "S": n_u * n_x,
                 "R": n_u * n_u, "q": n_x, "r": n_u, "idxbx": n_bx, "lbx": n_bx, "ubx": n_bx,
                 "idxbu": n_bu, "lbu": n_bu, "ubu": n_bu, "C": n_g * n_x, "D": n_g * n_u,
                 "lg": n_g, "ug": n_g}
        self.data: dict[str, np.ndarray] = {}
        self.offsets: dict[str, np.ndarray] = {}
        self._pointers: dict[str, ctypes.Array] = {}
        for name in _FIELDS:
            dtype = np.intc if name.startswith("idx") else np.float64
            self.data[name], self.offsets[name], self._pointers[name] = self._field(
                sizes[name], dtype)
        self._empty = self._field(np.zeros(self.K + 1, dtype=int), np.float64)[2]
        self._empty_int = self._field(np.zeros(self.K + 1, dtype=int), np.intc)[2]
        out_sizes = {"u": n_u, "x": n_x, "pi": nxn, "lam_lb": n_bx + n_bu,
                     "lam_ub": n_bx + n_bu, "lam_lg": n_g, "lam_ug": n_g}
        self.solution: dict[str, np.ndarray] = {}
        self._solution_offsets: dict[str, np.ndarray] = {}
        self._solution_pointers: dict[str, ctypes.Array] = {}
        for name in _SOLUTION:
            (self.solution[name], self._solution_offsets[name],
             self._solution_pointers[name]) = self._field(out_sizes[name], np.float64)

    # memory ------------------------------------------------------------------------------------
    def _memory(self, size: int) -> ctypes.Array:
        buf = ctypes.create_string_buffer(int(size) + 64)
        self._keep.append(buf)
        return buf

    def _struct(self, size: int) -> ctypes.Array:
        return self._memory(size)

    def _ptr(self, arr: np.ndarray) -> ctypes.c_void_p:
        self._keep.append(arr)
        return ctypes.c_void_p(arr.ctypes.data)

    def _field(self, sizes: np.ndarray, dtype) -> tuple[np.ndarray, np.ndarray, ctypes.Array]:
        """A flat buffer for per-stage blocks of ``sizes`` entries, the offsets and the array
        of per-stage pointers into it."""
        sizes = np.asarray(sizes, dtype=np.int64)
        offsets = np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(np.int64)
        buf = np.zeros(max(int(sizes.sum()), 1), dtype=dtype)
        addresses = (buf.ctypes.data + offsets * buf.itemsize).astype(np.uint64)
        pointers = (ctypes.c_void_p * (self.K + 1))(*addresses.tolist())
        self._keep.append(buf)
        return buf, offsets, pointers

    def view(self, name: str, k: int, shape: tuple[int, ...]) -> np.ndarray:
        """Stage ``k``'s block of field ``name`` (row-major, writable view)."""
        start = int(self.offsets[name][k])
        return self.data[name][start:start + int(np.prod(shape))].reshape(shape)

    def solution_view(self, name: str, k: int) -> np.ndarray:
        """Stage ``k``'s part of the solution field ``name`` (after :meth:`solve`)."""
        offsets = self._solution_offsets[name]
        end = offsets[k + 1] if k < self.K else self.solution[name].size
        return self.solution[name][int(offsets[k]):int(end)]

    # solve -------------------------------------------------------------------------------------
    def solve(self, masks=()) -> HpipmResult:
        """Load the current :attr:`data` into HPIPM and solve.

        Parameters
        ----------
        masks : sequence of (field, stage, ndarray)
            Bounds switched off (an infinite bound): ``field`` in lbx, ubx, lbu, ubu, lg, ug;
            the mask holds 1.0 for an active entry, 0.0 for an inactive one (its value in
            :attr:`data` must be finite, e.g. 0).
        """
        lib = hpipm_library()
        p = self._pointers
        e, ei = self._empty, self._empty_int
        slack_indices = (ei, ei) if _set_all_has_idxs_rev else (ei,)
        lib.d_ocp_qp_set_all_rowmaj(
            p["A"], p["B"], p["b"], p["Q"], p["S"], p["R"], p["q"], p["r"], p["idxbx"],
            p["lbx"], p["ubx"], p["idxbu"], p["lbu"], p["ubu"], p["C"], p["D"], p["lg"],
            p["ug"], e, e, e, e, *slack_indices, e, e, self.qp)
        for field, k, mask in masks:
            mask = np.ascontiguousarray(mask, dtype=np.float64)
            getattr(lib, f"d_ocp_qp_set_{field}_mask")(ctypes.c_int(k),
                                                       ctypes.c_void_p(mask.ctypes.data),
                                                       self.qp)
        lib.d_ocp_qp_ipm_solve(self.qp, self.sol, self.arg, self.ws)
        status, iters = ctypes.c_int(), ctypes.c_int()
        lib.d_ocp_qp_ipm_get_status(self.ws, ctypes.byref(status))
        lib.d_ocp_qp_ipm_get_iter(self.ws, ctypes.byref(iters))
        residuals = {}
        for name in ("stat", "eq", "ineq", "comp"):
            value = ctypes.c_double()
            getattr(lib, f"d_ocp_qp_ipm_get_max_res_{name}")(self.ws, ctypes.byref(value))
            residuals[name] = float(value.value)
        s = self._solution_pointers
        lib.d_ocp_qp_sol_get_all_rowmaj(self.sol, s["u"], s["x"], e, e, s["pi"], s["lam_lb"],
                                        s["lam_ub"], s["lam_lg"], s["lam_ug"], e, e)
        code = int(status.value)
        return HpipmResult(code, HPIPM_STATUS.get(code, "unknown flag"), int(iters.value),
                           residuals)

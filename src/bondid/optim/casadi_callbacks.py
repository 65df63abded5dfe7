"""CasADi functions evaluated in Python: the objective's callbacks and IPOPT's per-iteration
hook (:class:`casadi.Callback` subclasses, built on first use so that importing this module
does not import CasADi)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from .. import interrupt


def numpy_callback_class() -> Any:
    import casadi

    class NumpyCallback(casadi.Callback):
        """A CasADi function of dense column inputs evaluated by a Python function."""

        def __init__(
            self,
            name: str,
            in_sizes: list[int],
            out_shapes: list[tuple[int, int]],
            fn: Callable,
            jacobian: Callable[[Any], Any] | None = None,
        ):
            casadi.Callback.__init__(self)
            self._in, self._out, self._fn, self._jac = in_sizes, out_shapes, fn, jacobian
            self.construct(name, {"enable_fd": False})

        def has_jacobian(self) -> bool:
            return self._jac is not None

        def get_jacobian(self, name: str, inames: Any, onames: Any, opts: Any) -> Any:
            # only used for the one-input objective: d f / d z
            z = casadi.MX.sym("z", self._in[0])
            nominal = [casadi.MX.sym(f"out{i}", *s) for i, s in enumerate(self._out)]
            assert self._jac is not None
            return casadi.Function(name, [z, *nominal], [self._jac(z)], inames, onames, opts)

        def get_n_in(self) -> int:
            return len(self._in)

        def get_n_out(self) -> int:
            return len(self._out)

        def get_sparsity_in(self, i: int) -> Any:
            return casadi.Sparsity.dense(self._in[i], 1)

        def get_sparsity_out(self, i: int) -> Any:
            return casadi.Sparsity.dense(*self._out[i])

        def eval(self, arg: Any) -> Any:
            out = self._fn(*[np.asarray(a, dtype=float).reshape(-1) for a in arg])
            return [
                casadi.DM(np.asarray(o, dtype=float).reshape(s))
                for o, s in zip(out, self._out, strict=True)
            ]

    return NumpyCallback


def iteration_callback_class() -> Any:
    import casadi

    class IterationCallback(casadi.Callback):
        """IPOPT's per-iteration hook: hands ``(f, x, g, lam_x, lam_g)`` to ``record``, which
        returns True to stop the solve (IPOPT then ends with ``User_Requested_Stop``)."""

        def __init__(self, nx: int, ng: int, record: Callable[..., bool]):
            casadi.Callback.__init__(self)
            self._nx, self._ng, self._record = nx, ng, record
            #: the error ``record`` raised, which stopped the solve (None: none)
            self.error: Exception | None = None
            self.construct("fit_iteration", {})

        def get_n_in(self) -> int:
            return casadi.nlpsol_n_out()

        def get_n_out(self) -> int:
            return 1

        def get_name_in(self, i: int) -> str:
            return casadi.nlpsol_out(i)

        def get_name_out(self, i: int) -> str:
            return "ret"

        def get_sparsity_in(self, i: int) -> Any:
            name = casadi.nlpsol_out(i)
            if name == "f":
                return casadi.Sparsity.dense(1, 1)
            if name in ("x", "lam_x"):
                return casadi.Sparsity.dense(self._nx, 1)
            if name in ("g", "lam_g"):
                return casadi.Sparsity.dense(self._ng, 1)
            return casadi.Sparsity(0, 0)

        def eval(self, arg: Any) -> Any:
            names = casadi.nlpsol_out()

            def col(name: str) -> np.ndarray:
                return np.asarray(arg[names.index(name)], dtype=float).reshape(-1)

            try:
                stop = self._record(
                    float(arg[names.index("f")]), col("x"), col("g"), col("lam_x"), col("lam_g")
                )
            except Exception as exc:  # handed to the solve's caller
                # an error raised through CasADi is printed there with the whole iterate and
                # a traceback; kept here instead, it stops IPOPT and the solve reports it
                self.error = exc
                stop = True
            # non-zero asks IPOPT to stop (User_Requested_Stop): the caller's own reason, or
            # a Ctrl-C that CasADi caught
            return [1 if stop or interrupt.requested() else 0]

    return IterationCallback

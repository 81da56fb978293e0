"""Algebraic loops across FMUs: Newton's method on the torn connections' inputs.

In each cycle of direct feedthrough the connection given first is torn
(:meth:`heliostep.cosim.connections.ConnectionGraph._propagation_order`): its input becomes an
iteration variable ``v`` and the loop is solved when the torn source output ``y(v) = v`` (Newton with a
forward-difference Jacobian from the previous solution; the last evaluation at the accepted ``v``, so
every FMU is left consistent). The compiled kernel solves the same loops the same way in C from the
same guess :attr:`LoopSolver.v`; this class solves them at events and on the Python path.

The first solve, at initialization before any row, also checks that the loop has a unique solution:
a singular Jacobian there (at the start or at a Newton step) is bad input, :class:`SingularLoop` (an
:class:`~heliostep.errors.InputError`, exit 2), whatever entry point runs it; later, a run failure. A
loop Newton cannot solve (no real solution, or its tolerances ``loop_rtol`` and ``loop_atol`` of
:class:`~heliostep.cosim.signals.SolverOptions` out of reach) is a :class:`LoopError` naming its torn
inputs, their last values and residuals, and the time.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from heliostep.cosim.signals import SolverOptions
from heliostep.errors import InputError, RunFailure


class LoopError(RunFailure):
    """Newton's method found no solution of an algebraic loop (a run failure, raised while simulating)."""


class SingularLoop(InputError):
    """An algebraic loop without a unique solution, found at its first solve, at initialization (exit 2)."""


class LoopSolver:
    """Solves the torn inputs of all algebraic loops at once.

    ``write(v)`` sets the torn inputs, ``propagate()`` copies the other connections in order,
    ``read()`` returns the torn sources' outputs.
    """

    def __init__(
        self,
        names: list[str],
        write: Callable[[np.ndarray], None],
        read: Callable[[], np.ndarray],
        rtol: float = SolverOptions.loop_rtol,
        atol: float = SolverOptions.loop_atol,
        max_iterations: int = 50,
    ):
        self.names = names
        self.write, self.read = write, read
        self.rtol, self.atol, self.max_iterations = rtol, atol, max_iterations
        self.v = np.zeros(len(names))
        self.solves = 0
        self.iterations = 0
        self.most_iterations = 0
        #: the compiled kernel's (solves, iterations, most iterations), when it solves the loops too
        self.compiled_counts: Callable[[], tuple[int, int, int]] | None = None

    def _residual(self, v: np.ndarray, propagate: Callable[[], None]) -> np.ndarray:
        self.write(v)
        propagate()
        return self.read() - v

    def solve(self, propagate: Callable[[], None], time: float) -> None:
        """Find v with y(v) = v, leaving every FMU evaluated at that v."""
        v = self.v.copy()
        self.solves += 1
        r = self._residual(v, propagate)
        if self.solves == 1:  # the first solve checks the loop has a unique solution, even one met at once
            self._check_unique(v, r, propagate, time)
            r = self._residual(v, propagate)  # every FMU left evaluated at v
        for iteration in range(self.max_iterations + 1):
            if np.all(np.abs(r) <= self.atol + self.rtol * np.abs(v)) and np.all(np.isfinite(r)):
                self.v[:] = v  # in place: the compiled kernel reads it
                self.iterations += iteration
                self.most_iterations = max(self.most_iterations, iteration)
                return
            if iteration == self.max_iterations or not np.all(np.isfinite(r)):
                break
            try:
                step = np.linalg.solve(self._jacobian(v, r, propagate), -r)
            except np.linalg.LinAlgError:  # at the first solve, initialization: a loop without a unique solution
                raise (SingularLoop(self.singular(time)) if self.solves == 1 else self.breakdown(time)) from None
            v = v + step
            r = self._residual(v, propagate)
        raise self.no_convergence(time, v, r)

    def no_convergence(self, time: float, v: np.ndarray, r: np.ndarray) -> LoopError:
        """The error of a loop not solved in ``max_iterations`` at ``time`` [s]: each torn input's last
        value ``v`` and residual ``r`` = y(v) - v, and the tolerance they missed."""
        residuals = ", ".join(f"{abs(ri):.3g} at {name} = {vi:.9g}" for name, vi, ri in zip(self.names, v, r))
        return LoopError(
            f"algebraic loop through {', '.join(self.names)} at t = {time:.9g} s: no convergence in "
            f"{self.max_iterations} Newton iterations, residual {residuals} (solved when |residual| <= "
            f"solver.loop_atol + solver.loop_rtol |value| = {self.atol:.3g} + {self.rtol:.3g} |value|)"
        )

    def _jacobian(self, v: np.ndarray, r: np.ndarray, propagate: Callable[[], None]) -> np.ndarray:
        """Forward differences of r at v (one evaluation per torn input), each step 1e-7 of the larger of
        v and y(v) = v + r (and of 1): a step below rounding of a large y would leave r unchanged (from
        the first guess 0 of a loop whose values are large, a Jacobian of exactly 0)."""
        jacobian = np.empty((len(v), len(v)))
        for j in range(len(v)):
            h = 1e-7 * max(1.0, abs(v[j]), abs(v[j] + r[j]))
            perturbed = v.copy()
            perturbed[j] += h
            jacobian[:, j] = (self._residual(perturbed, propagate) - r) / h
        return jacobian

    def _check_unique(self, v: np.ndarray, r: np.ndarray, propagate: Callable[[], None], time: float) -> None:
        """A loop whose Jacobian is singular (e.g. y = u fed back to u: every v solves it) has no unique
        solution: refused as bad input, naming the loop, rather than accepted at whatever v it starts from."""
        jacobian = self._jacobian(v, r, propagate)
        if not np.all(np.isfinite(jacobian)) or np.linalg.cond(jacobian) > 1e12:
            raise SingularLoop(self.singular(time))

    def breakdown(self, time: float) -> LoopError:
        """The error of a singular Jacobian met by Newton at ``time`` [s] (a run failure)."""
        return LoopError(self.singular(time))

    def singular(self, time: float) -> str:
        """What a singular Jacobian at ``time`` [s] says about the loop."""
        return (
            f"algebraic loop through {', '.join(self.names)} at t = {time:.9g} s: "
            "singular Jacobian (the loop has no unique solution)"
        )

    def statistics(self) -> dict:
        """Solves, Newton iterations and the most in one solve: this solver's and the compiled kernel's."""
        solves, iterations, most = self.compiled_counts() if self.compiled_counts is not None else (0, 0, 0)
        return {
            "loop_solves": self.solves + solves,
            "loop_iterations": self.iterations + iterations,
            "loop_most_iterations": max(self.most_iterations, most),
            "loop_solves_compiled": solves,
        }

"""How many steps other integrators need for one motor step and its ring (prints figures; not a test).

    .venv/bin/python benchmarks/ring_integrators.py [--rtol 1e-6] [--atol 1e-6]

An independent model written here in numpy (eqs 7-10 of the paper with the shipped parameters,
docs/physics.md; not the FMUs): the averaged chopper, the detent torque and the panel mechanics
with Coulomb friction. It starts at the holding equilibrium of phase A, switches the reference
to phase B at t = 0 (one full step) and integrates 0.2 s: the step, the ring (9 ms period) and
the creep into the detent. Printed per integrator of scipy.integrate.solve_ivp (BDF: variable
order 1-5 like CVODE; Radau: fifth-order, L-stable implicit Runge-Kutta; LSODA) at the same
tolerances as a scenario (rtol, atol = rtol x nominal 1): steps, RHS evaluations, Jacobians
(scipy's finite differences count as RHS evaluations too) and the peak torque, beside what
CVODE takes for a motor step of the paper's case (benchmarks/solver_cost.py: 613 steps, 1 007
RHS). It shows whether the cost is CVODE's or the ring's.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from scipy.integrate import solve_ivp

# models/StepperMotor.mo and models/PanelMechanics.mo (Tables 2 and 3 of the paper, docs/physics.md)
L, R, K_E, N_C, V_SUPPLY, K_CURRENT = 1.8e-3, 0.1, 0.5, 50.0, 3.1, 100.0
J_P, J_M, B, T_C, M_C, W_S, R_PINION, S_LEVER = 3.37, 1.4e-4, 0.0, 0.08, 3.3e-3, 1e-2, 2.5e-3, 0.3
CURRENT = 5.5  # [A] the paper's case (scenarios/jan21-central.yaml)
THETA_P0 = 0.48  # [rad] the panel near 27.5 deg, as at 10:00 on 21 January


def rhs(_t, y, i_a_ref, i_b_ref):
    """der of (i_a, i_b, theta_p, omega_p), and the torque [N.m]."""
    i_a, i_b, theta_p, omega_p = y
    theta = S_LEVER / R_PINION * (np.tan(theta_p) - np.tan(THETA_P0))  # eqs 12-14
    g = S_LEVER / (R_PINION * np.cos(theta_p) ** 2)  # eq 15
    omega = g * omega_p
    v_a = np.clip(K_CURRENT * (i_a_ref - i_a), -V_SUPPLY, V_SUPPLY)
    v_b = np.clip(K_CURRENT * (i_b_ref - i_b), -V_SUPPLY, V_SUPPLY)
    di_a = (v_a - R * i_a + K_E * omega * np.sin(N_C * theta)) / L  # eq 7
    di_b = (v_b - R * i_b + K_E * omega * np.cos(N_C * theta)) / L  # eq 8
    torque = -K_E * i_a * np.sin(N_C * theta) - K_E * i_b * np.cos(N_C * theta)  # eq 9
    friction = (T_C + M_C * R_PINION * np.cos(theta_p) ** 2 / S_LEVER) * np.tanh(omega / W_S)
    domega_p = (g * (torque - friction) - B * omega_p - J_M * g * 2 * g * np.tan(theta_p) * omega_p**2) / (
        J_P + J_M * g**2
    )  # eq 10, the exact (Lagrangian) form
    return np.array([di_a, di_b, omega_p, domega_p]), torque


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rtol", type=float, default=1e-6)
    parser.add_argument("--atol", type=float, default=None, help="default: rtol x nominal 1, as a scenario")
    args = parser.parse_args()
    atol = args.rtol if args.atol is None else args.atol
    held = K_CURRENT * CURRENT / (K_CURRENT + R)  # the loop's holding current, L di/dt = 0
    y0 = np.array([held, 0.0, THETA_P0, 0.0])
    print(f"one full step (phase A -> B, {CURRENT} A) and 0.2 s of ring and creep, rtol {args.rtol:g}, atol {atol:g}:")
    for method in ("BDF", "Radau", "LSODA"):
        started = time.perf_counter()
        solution = solve_ivp(
            lambda t, y: rhs(t, y, 0.0, CURRENT)[0], (0.0, 0.2), y0, method=method, rtol=args.rtol, atol=atol
        )
        wall = time.perf_counter() - started
        if not solution.success:
            print(f"  {method:6s} failed: {solution.message}")
            continue
        torque = np.array([rhs(t, y, 0.0, CURRENT)[1] for t, y in zip(solution.t, solution.y.T)])
        theta = S_LEVER / R_PINION * (np.tan(solution.y[2]) - np.tan(THETA_P0))
        ring = solution.t[(solution.t > 5e-3) & (solution.t < 50e-3)]
        print(
            f"  {method:6s} {len(solution.t) - 1:6d} steps ({len(ring):5d} of them 5-50 ms after the step) "
            f"{solution.nfev:7d} RHS {solution.njev:4d} Jacobians  peak torque {np.abs(torque).max():.4f} N.m  "
            f"rotor moved {theta[-1] / (np.pi / (2 * N_C)):+.4f} steps  ({wall:.1f} s)"
        )
    print("  CVODE (BDF) in heliostep, a motor step of the paper's case: 613 steps, 1 007 RHS (solver_cost.py)")


if __name__ == "__main__":
    main()

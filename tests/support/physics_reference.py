"""An independent numpy implementation of the drive equations, for checking the FMUs.

Written from docs/physics.md (the paper's eqs [7]-[15] and Tables 2-3), not from the
Modelica sources, so that a sign or factor slip in a model shows up as a mismatch.
"""

import numpy as np

#: Table 3 of the paper (motor), SI units.
TABLE3_MOTOR = {"L": 1.8e-3, "R": 0.1, "k_e": 0.5, "N_c": 50.0, "V_supply": 3.1}
RATED_CURRENT = 5.5  # [A], Table 3
STEP_ANGLE = np.radians(1.8)  # [rad], Table 3 = pi / (2 N_c)
#: The averaged chopper's loop gain K [V/A] (the motor FMU's default, docs/physics.md, the driver) and the
#: current it holds for the rated reference: L di/dt = K (I - i) - R i = 0 at i = K I / (K + R).
K_CURRENT = 100.0
HELD_CURRENT = K_CURRENT * RATED_CURRENT / (K_CURRENT + TABLE3_MOTOR["R"])

#: The motor's losses (docs/physics.md, "The motor's losses"): rotor damping B_m [N.m.s/rad] on the
#: shaft, iron-loss conductance G_m = 1/R_m [S] across each back-EMF, detent torque T_d [N.m] with
#: 4 N_c periods per turn -- the terms of MATLAB/Simscape Electrical's Stepper Motor block.
MOTOR_LOSSES = {"B_m": 0.0, "G_m": 0.0, "T_d": 0.094}

#: Table 2 of the paper (panel), SI units.
TABLE2_PANEL = {"J_p": 3.37, "r": 2.5e-3, "s": 0.3, "l": 1.5, "sp": 0.05, "M": 18.0}


def _torque(i_a, i_b, theta, omega, k_e, N_c, G_m, T_d):
    """Eq. 9 with the iron loss and the detent torque: the torque-making current is i - e/R_m, with the
    back-EMF e_a = -k_e omega sin(N_c theta), e_b = -k_e omega cos(N_c theta) (the sign of eqs. 7-8),
    and the detent torque -T_d sin(4 N_c theta) has its stable points at the full steps."""
    e_a, e_b = -k_e * omega * np.sin(N_c * theta), -k_e * omega * np.cos(N_c * theta)
    electromagnetic = -k_e * (i_a - G_m * e_a) * np.sin(N_c * theta) - k_e * (i_b - G_m * e_b) * np.cos(N_c * theta)
    return electromagnetic - T_d * np.sin(4 * N_c * theta)


def stepper_motor(
    i_a, i_b, i_a_ref, i_b_ref, theta, omega, *, L, R, k_e, N_c, V_supply, K_current, G_m=0.0, T_d=MOTOR_LOSSES["T_d"]
):
    """Averaged-chopper motor: returns di_a/dt, di_b/dt, torque, v_a, v_b, power."""
    v_a = np.clip(K_current * (i_a_ref - i_a), -V_supply, V_supply)
    v_b = np.clip(K_current * (i_b_ref - i_b), -V_supply, V_supply)
    di_a = (v_a - R * i_a + k_e * omega * np.sin(N_c * theta)) / L  # eq. 7
    di_b = (v_b - R * i_b + k_e * omega * np.cos(N_c * theta)) / L  # eq. 8
    torque = _torque(i_a, i_b, theta, omega, k_e, N_c, G_m, T_d)  # eq. 9 with the losses
    return di_a, di_b, torque, v_a, v_b, v_a * i_a + v_b * i_b


def ideal_current_motor(
    i_a, i_b, i_a_ref, i_b_ref, theta, omega, *, L, R, k_e, N_c, T_current, G_m=0.0, T_d=MOTOR_LOSSES["T_d"]
):
    """Currents lag their references; voltages from eqs 7-8 solved for v."""
    di_a = (i_a_ref - i_a) / T_current
    di_b = (i_b_ref - i_b) / T_current
    v_a = L * di_a + R * i_a - k_e * omega * np.sin(N_c * theta)
    v_b = L * di_b + R * i_b - k_e * omega * np.cos(N_c * theta)
    torque = _torque(i_a, i_b, theta, omega, k_e, N_c, G_m, T_d)
    return di_a, di_b, torque, v_a, v_b, v_a * i_a + v_b * i_b


def panel_mechanics(
    theta_p,
    omega_p,
    torque,
    m_ext,
    *,
    J_p,
    J_m,
    b,
    r,
    s,
    theta_p_start,
    theta_start,
    small_angle=False,
    T_c=0.08,
    M_c=3.3e-3,
    w_s=1e-2,
    B_m=0.0,
    karnopp=False,
    T_stick=1e-3,
):
    """Returns dtheta_p/dt, domega_p/dt, rotor angle, rotor speed.

    Exact form: Lagrange's equation with T = J_p w_p^2/2 + J_m (g w_p)^2/2 gives
    (J_p + J_m g^2) dw_p/dt + J_m g g' w_p^2 = g (C - T_f - B_m w) - b w_p - M_ext, g' = dg/dtheta_p,
    with Coulomb friction T_f = (T_c + M_c/g) tanh(g w_p / w_s) (smoothed; docs/physics.md), or with
    ``karnopp`` Karnopp's stick-slip friction: T_f = (T_c + M_c/g) sign(w) for |w| >= w_s, and for
    |w| < w_s the torque that holds the rotor (everything else on the shaft, so that dw/dt = -w / T_stick),
    clipped to +-(T_c + M_c/g).
    """
    if small_angle:
        ratio = s / r
        dratio = 0.0
        theta = theta_start + ratio * (theta_p - theta_p_start)
    else:
        ratio = s / (r * np.cos(theta_p) ** 2)  # eq. 15
        dratio = 2 * ratio * np.tan(theta_p)  # d/dtheta_p of s / (r cos^2 theta_p)
        theta = theta_start + s / r * (np.tan(theta_p) - np.tan(theta_p_start))  # eqs. 12-14
    omega = ratio * omega_p
    friction = (T_c + M_c / ratio) * np.tanh(omega / w_s)
    if karnopp:
        cap = T_c + M_c / ratio
        others = (b * omega_p + m_ext + J_m * ratio * dratio * omega_p**2) / ratio
        held = torque - B_m * omega - others + (J_p / ratio**2 + J_m) * omega / T_stick
        friction = np.where(np.abs(omega) < w_s, np.clip(held, -cap, cap), cap * np.sign(omega))
    domega_p = (ratio * (torque - friction - B_m * omega) - b * omega_p - m_ext - J_m * ratio * dratio * omega_p**2) / (
        J_p + J_m * ratio**2
    )  # eq. 10, exact form
    return omega_p, domega_p, theta, omega

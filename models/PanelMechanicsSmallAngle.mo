model PanelMechanicsSmallAngle
  "Secondary-axis drive with the paper's literal eq [10]: constant ratio s/r (cos theta_p = 1)"
  // Same interface and parameters as PanelMechanics (see it and docs/physics.md for the
  // sources). The paper writes C s/r = J_p der(omega_p) [10], i.e. the transmission ratio at
  // theta_p = 0; J_m = b = B_m = T_c = M_c = 0 give that equation to the letter. With a constant
  // ratio the Lagrangian has no velocity-squared term.
  parameter Real J_p(unit = "kg.m2") = 3.37 "Panel inertia about its hinge, M/12 (l^2 + sp^2) [11] (Table 2)";
  parameter Real J_m(unit = "kg.m2") = 1.4e-4 "Rotor inertia on the motor shaft (NEMA 34 class catalogue value)";
  parameter Real b(unit = "N.m.s/rad") = 0 "Viscous damping on the panel axis (none sourced: 0)";
  parameter Real B_m(unit = "N.m.s/rad") = 0 "Viscous damping of the rotor on the motor shaft (none sourced: 0)";
  parameter Real T_c(unit = "N.m") = 0.08 "Coulomb friction of reducer + rack on the motor shaft";
  parameter Real M_c(unit = "N.m") = 3.3e-3 "Coulomb friction of the hinge bearings on the panel axis";
  parameter Real w_s(unit = "rad/s") = 1e-2 "Regularisation speed of the Coulomb friction (rotor speed)";
  parameter Real r(unit = "m") = 2.5e-3 "Pinion radius after the reducer (Table 2)";
  parameter Real s(unit = "m") = 0.3 "Lever arm of the rack on the panel (Table 2)";
  parameter Real theta_p_start(unit = "rad") = 0 "Initial panel angle";
  parameter Real theta_start(unit = "rad") = 0 "Rotor angle at the initial panel angle";
  input Real tau(unit = "N.m") "Motor torque on the rotor";
  input Real m_ext(unit = "N.m") "External moment on the panel (wind), opposing positive rotation";
  output Real theta(unit = "rad") "Rotor angle";
  output Real omega(unit = "rad/s") "Rotor speed";
  output Real theta_p(unit = "rad", start = theta_p_start, fixed = true) "Panel angle";
  output Real omega_p(unit = "rad/s", start = 0, fixed = true) "Panel speed";
  output Real tau_friction(unit = "N.m") "Friction torque on the motor shaft (bearings referred to it)";
equation
  der(theta_p) = omega_p;
  tau_friction = (T_c + M_c * r / s) * tanh(omega / w_s);
  (J_p + J_m * (s / r)^2) * der(omega_p) = s / r * (tau - tau_friction - B_m * omega) - b * omega_p - m_ext;  // [paper], eq. 10
  theta = theta_start + s / r * (theta_p - theta_p_start);  // [paper], eqs. 12-14, small angle
  omega = s / r * omega_p;  // [paper], eq. 15, small angle
end PanelMechanicsSmallAngle;

model PanelMechanicsKarnopp
  "PanelMechanics with Karnopp stick-slip friction instead of the tanh: the rotor sticks anywhere it can be held"
  // The rack travel is r*dtheta [12] and s*d(tan theta_p) [13], so the rotor angle is
  // theta = theta_start + (s/r)*(tan theta_p - tan theta_p_start) [14] and the speed ratio
  // g = dtheta/dtheta_p = s/(r cos^2 theta_p) [15]. With kinetic energy
  // T = J_p omega_p^2/2 + J_m (g omega_p)^2/2, Lagrange's equation is the exact form of [10]:
  //   (J_p + J_m g^2) der(omega_p) + J_m g (dg/dtheta_p) omega_p^2
  //       = g (tau - tau_friction - B_m omega) - b omega_p - M_ext,
  // with dg/dtheta_p = 2 g tan(theta_p). Friction is Coulomb friction in Karnopp's stick-slip form
  // (below) where PanelMechanics smooths it by tanh; see docs/physics.md for every parameter's source.
  parameter Real J_p(unit = "kg.m2") = 3.37 "Panel inertia about its hinge, M/12 (l^2 + sp^2) [11] (Table 2)";
  // J_m: the paper gives no rotor inertia. Catalogue class: NEMA 34 (86 mm frame) two-phase
  // hybrid stepper of about 2.2-3 N.m holding torque (ours: k_e*I = 2.75 N.m), rotor inertia
  // 1400 g.cm2 (e.g. Oriental Motor PKP296 series, 86 mm, 1.8 deg: rotor inertia 1400 g.cm2).
  // The reducer's own inertia is not included (no reducer is named by the paper).
  parameter Real J_m(unit = "kg.m2") = 1.4e-4 "Rotor inertia on the motor shaft (NEMA 34 class catalogue value)";
  // b: no sourced viscous friction for this drive; 0 by default (kept for studies).
  parameter Real b(unit = "N.m.s/rad") = 0 "Viscous damping on the panel axis (none sourced: 0)";
  // B_m: viscous damping of the rotor on the motor shaft, none sourced: 0 (PanelMechanics).
  parameter Real B_m(unit = "N.m.s/rad") = 0 "Viscous damping of the rotor on the motor shaft (none sourced: 0)";
  // T_c: Coulomb friction of the reducer and the rack-and-pinion, referred to the motor shaft.
  // Source: a single planetary stage loses about 3 % of the torque it transmits (typical
  // catalogue efficiency 97 % per stage); at the motor's rated holding torque k_e*I = 2.75 N.m
  // that is T_c = 0.03*2.75 = 0.08 N.m, taken as a load-independent Coulomb torque.
  parameter Real T_c(unit = "N.m") = 0.08 "Coulomb friction of reducer + rack on the motor shaft";
  // M_c: the panel's two hinge ball bearings, SKF's simplified friction moment
  // M = 0.5*mu*P*d with mu = 0.0015 (deep-groove ball bearing), P = M g = 18*9.81 N (Table 2
  // mass) and an assumed bore d = 25 mm: 3.3e-3 N.m on the panel axis.
  parameter Real M_c(unit = "N.m") = 3.3e-3 "Coulomb friction of the hinge bearings on the panel axis";
  // Karnopp's stick-slip model (D. Karnopp, "Computer simulation of stick-slip friction in mechanical
  // dynamic systems", J. Dyn. Sys., Meas., Control 107, 1985): outside a band |omega| < w_s the
  // friction is the full Coulomb torque against the motion; inside it, the friction is whatever holds
  // the rotor (the torque applied to the shaft), up to that Coulomb torque: a rotor held by less than
  // T_c sticks where it is instead of creeping into its detent. The model's FMU has no state events
  // (the export declares none), so the switch is a discontinuity CVODE steps over by its error test;
  // inside the band the speed relaxes to 0 with T_stick (a speed left in the band would otherwise
  // drift the stuck rotor). docs/physics.md gives the figures and the cost against the tanh.
  parameter Real w_s(unit = "rad/s") = 1e-2 "Karnopp's stick band: below this rotor speed the rotor sticks";
  parameter Real T_stick(unit = "s") = 1e-3 "Relaxation time of the rotor speed while it sticks";
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
  Real g(unit = "1") "Speed ratio dtheta/dtheta_p";
  Real t_cap(unit = "N.m") "Coulomb friction torque on the motor shaft (bearings referred to it)";
  Real t_held(unit = "N.m") "Friction torque that holds the rotor still (and relaxes its speed)";
equation
  g = s / (r * cos(theta_p)^2);  // [paper], eq. 15
  der(theta_p) = omega_p;
  t_cap = T_c + M_c * r * cos(theta_p)^2 / s;  // M_c / g
  // the torque on the shaft but friction's, from the equation of motion below, plus J_eff omega / T_stick
  t_held = tau - B_m * omega - (b * omega_p + m_ext + J_m * g * (2 * g * tan(theta_p)) * omega_p^2) / g
    + (J_p / g^2 + J_m) * omega / T_stick;
  tau_friction = if abs(omega) < w_s then min(max(t_held, -t_cap), t_cap) else (if omega > 0 then t_cap else -t_cap);
  (J_p + J_m * g^2) * der(omega_p) + J_m * g * (2 * g * tan(theta_p)) * omega_p^2
    = g * (tau - tau_friction - B_m * omega) - b * omega_p - m_ext;  // [paper], eq. 10 (exact form, full Lagrangian)
  theta = theta_start + s / r * (tan(theta_p) - tan(theta_p_start));  // [paper], eqs. 12-14
  omega = g * omega_p;  // [paper], eq. 15
end PanelMechanicsKarnopp;

model PanelMechanicsSmallAngle
  "Secondary-axis drive with the paper's literal eq [10]: constant ratio s/r (cos theta_p = 1)"
  // Same interface as PanelMechanics. The paper writes C s/r = J_p der(omega_p) [10], i.e. the
  // transmission ratio at theta_p = 0; J_m = 0 and b = 0 give that equation to the letter.
  parameter Real J_p(unit = "kg.m2") = 3.37 "Panel inertia about its hinge, M/12 (l^2 + sp^2) [11] (Table 2)";
  // J_m: rotor inertia of a hybrid stepper of this size (holding torque k_e*I = 2.75 N.m,
  // NEMA 34 class), whose catalogue rotor inertias are of the order of 1-3 kg.cm2; the
  // reducer's own inertia is small beside it. The paper gives no value.
  parameter Real J_m(unit = "kg.m2") = 1.4e-4 "Rotor + gear inertia referred to the motor shaft";
  // b: the paper reports a first-order-like step response with no settling oscillation but
  // gives no damping. With the current loop holding the phase currents, the rotor sits in a
  // detent of stiffness k = k_e*I*N_c = 137.5 N.m/rad (rated current); referred to the
  // panel at theta_p = 0 (g = s/r = 120) critical damping is
  // b = 2*g^2*sqrt(k*(J_m + J_p/g^2)) = 6.53e3 N.m.s/rad. b = 6500 makes one step settle
  // without ringing (damping ratio about 1); it lumps bearing, rack and drive losses.
  parameter Real b(unit = "N.m.s/rad") = 6500 "Viscous damping on the panel axis";
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
equation
  der(theta_p) = omega_p;
  (J_p + J_m * (s / r)^2) * der(omega_p) = s / r * tau - b * omega_p - m_ext;  // [paper], eq. 10
  theta = theta_start + s / r * (theta_p - theta_p_start);  // [paper], eqs. 12-14, small angle
  omega = s / r * omega_p;  // [paper], eq. 15, small angle
end PanelMechanicsSmallAngle;

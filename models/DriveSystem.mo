model DriveSystem
  "StepperMotor driving PanelMechanics: the monolithic twin of the co-simulation"
  StepperMotor motor "Motor electrics";
  PanelMechanics mechanics "Panel mechanics";
  input Real i_a_ref(unit = "A") "Reference current of phase A";
  input Real i_b_ref(unit = "A") "Reference current of phase B";
  input Real m_ext(unit = "N.m") "External moment on the panel (wind)";
  output Real tau(unit = "N.m") "Motor torque";
  output Real theta(unit = "rad") "Rotor angle";
  output Real theta_p(unit = "rad") "Panel angle";
equation
  connect(i_a_ref, motor.i_a_ref);
  connect(i_b_ref, motor.i_b_ref);
  connect(m_ext, mechanics.m_ext);
  connect(motor.tau, mechanics.tau);
  connect(mechanics.theta, motor.theta);
  connect(mechanics.omega, motor.omega);
  connect(motor.tau, tau);
  connect(mechanics.theta, theta);
  connect(mechanics.theta_p, theta_p);
end DriveSystem;

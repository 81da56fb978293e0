model StepperMotorIdealCurrent
  "Stepper motor whose phase currents follow their references through a first-order lag (no chopper)"
  // Same interface as StepperMotor. Torque from the paper's eq [9]; the voltages are the
  // ones the windings would need for the lagged currents, from eqs [7]-[8] solved for v.
  parameter Real L(unit = "H") = 1.8e-3 "Phase inductance L_a = L_b (Table 3)";
  parameter Real R(unit = "Ohm") = 0.1 "Phase resistance R_a = R_b (Table 3)";
  parameter Real k_e(unit = "N.m/A") = 0.5 "Torque constant k_e (Table 3)";
  parameter Real N_c(unit = "1") = 50 "Number of rotor teeth N_c (Table 3)";
  parameter Real T_current(unit = "s") = 1e-3 "Time constant of the current lag";
  // Iron loss and detent torque as in StepperMotor (its comments and docs/physics.md give the sources).
  parameter Real G_m(unit = "S") = 0 "Iron-loss conductance 1/Rm of the magnetising resistance (none sourced: 0)";
  parameter Real T_d(unit = "N.m") = 0.094 "Detent torque amplitude (TRINAMIC QSH8618 catalogue, interpolated)";
  parameter Real i_a_start(unit = "A") = 0 "Initial current of phase A";
  parameter Real i_b_start(unit = "A") = 0 "Initial current of phase B";
  input Real i_a_ref(unit = "A") "Reference current of phase A";
  input Real i_b_ref(unit = "A") "Reference current of phase B";
  input Real theta(unit = "rad") "Rotor angle";
  input Real omega(unit = "rad/s") "Rotor speed";
  output Real tau(unit = "N.m") "Electromagnetic torque on the rotor C";
  output Real i_a(unit = "A", start = i_a_start, fixed = true) "Current of phase A";
  output Real i_b(unit = "A", start = i_b_start, fixed = true) "Current of phase B";
  output Real v_a(unit = "V") "Voltage applied to phase A";
  output Real v_b(unit = "V") "Voltage applied to phase B";
  output Real power(unit = "W") "Electrical power drawn by both phases";
equation
  T_current * der(i_a) = i_a_ref - i_a;
  T_current * der(i_b) = i_b_ref - i_b;
  v_a = L * der(i_a) + R * i_a - k_e * omega * sin(N_c * theta);  // [paper], eq. 7
  v_b = L * der(i_b) + R * i_b - k_e * omega * cos(N_c * theta);  // [paper], eq. 8
  // [paper], eq. 9 with the Simscape block's iron-loss and detent terms (0 with G_m = T_d = 0)
  tau = -k_e * (i_a + G_m * k_e * omega * sin(N_c * theta)) * sin(N_c * theta)
    - k_e * (i_b + G_m * k_e * omega * cos(N_c * theta)) * cos(N_c * theta) - T_d * sin(4 * N_c * theta);
  power = v_a * i_a + v_b * i_b;
end StepperMotorIdealCurrent;

model StepperMotor
  "Two-phase bipolar hybrid stepper motor with an averaged chopper current control, eqs [7]-[9], iron loss and detent"
  // Source: the paper's eqs [7]-[9], restated in docs/physics.md.
  // Back-EMF sign: the one that makes electrical power in = mechanical power out with [9].
  // The chopper of each winding is modelled by its average: the drive applies
  // v = clamp(K (i_ref - i), -dV, +dV), i.e. a proportional current loop that saturates
  // at the supply voltage (a system-level model of the paper's "feedback control").
  parameter Real L(unit = "H") = 1.8e-3 "Phase inductance L_a = L_b (Table 3)";
  parameter Real R(unit = "Ohm") = 0.1 "Phase resistance R_a = R_b (Table 3)";
  parameter Real k_e(unit = "N.m/A") = 0.5 "Torque constant k_e (Table 3)";
  parameter Real N_c(unit = "1") = 50 "Number of rotor teeth N_c (Table 3)";
  parameter Real V_supply(unit = "V") = 3.1 "Chopper voltage limit dV (Table 3, rated voltage)";
  // K_current: no datasheet gives the averaged loop's gain. The sourced crossover (a tenth of the
  // TMC5160's 16-30 kHz chopper, 18-34 V/A for 1.8 mH) is the band's range, not the default: this
  // loop has no feed-forward of R i and the back-EMF, so at such a gain it would hold K I / (K + R)
  // and fall short by e / (K + R) under the back-EMF, errors a current-regulating chopper does not
  // have; 100 V/A keeps them a quarter as large (docs/physics.md, the driver).
  parameter Real K_current(unit = "V/A") = 100 "Current-loop gain K of the averaged chopper";
  // The motor's losses, in the form of MATLAB/Simscape Electrical's Stepper Motor block
  // (mathworks.com/help/sps/ref/steppermotor.html: Te = Km (iA - eA/Rm) sin(Nr theta) +
  // Km (iB - eB/Rm) cos(Nr theta) - Td sin(4 Nr theta), J dw/dt + B w = Te; the rotor damping B
  // is in the mechanics, beside the rotor inertia). Sources and ranges: docs/physics.md.
  // G_m: the iron losses as a magnetising resistance Rm across each winding's back-EMF e, written
  // as its conductance G_m = 1/Rm so that 0 means "no iron loss" (Rm = infinity). The current
  // that makes torque is i - e/Rm, so the loss brakes the rotor by k_e^2 G_m omega at any
  // position. No catalogue of this motor class gives Rm: 0 by default (docs/physics.md).
  parameter Real G_m(unit = "S") = 0 "Iron-loss conductance 1/Rm of the magnetising resistance (none sourced: 0)";
  // T_d: detent torque, the rotor magnet's pull on the stator teeth with the windings off; it
  // has 4 N_c periods per turn, its stable points at the full steps (the Simscape block's term).
  // Source: TRINAMIC, QMot QSH8618 manual V1.08, Table 2.1 (NEMA 34 hybrid steppers): detent
  // torque 0.078 N.m at a 3.4 N.m two-phase holding torque (QSH8618-65), 0.117 at 4.6 (-80), 0.235
  // at 8.7, 0.353 at 12.8: 2.3-2.8 % of it. The paper's motor holds sqrt(2) k_e I = 3.89 N.m with
  // both phases at 5.5 A; interpolated between the -65 and the -80 by holding torque: 0.094 N.m
  // (the catalogue's ratios give 0.089-0.107 N.m; docs/physics.md, "The motor's losses").
  parameter Real T_d(unit = "N.m") = 0.094 "Detent torque amplitude (TRINAMIC QSH8618 catalogue, interpolated)";
  // The run starts at the loop's holding equilibrium: with the rotor still, L di/dt = 0 gives
  // K (i_ref - i) = R i, i.e. i = K i_ref / (K + R) (while |R i| <= dV, the chopper unsaturated).
  parameter Real i_a_start(unit = "A") = 0 "Reference current of phase A held before the start";
  parameter Real i_b_start(unit = "A") = 0 "Reference current of phase B held before the start";
  input Real i_a_ref(unit = "A") "Reference current of phase A";
  input Real i_b_ref(unit = "A") "Reference current of phase B";
  input Real theta(unit = "rad") "Rotor angle";
  input Real omega(unit = "rad/s") "Rotor speed";
  output Real tau(unit = "N.m") "Electromagnetic torque on the rotor C";
  output Real i_a(unit = "A", start = K_current * i_a_start / (K_current + R), fixed = true) "Current of phase A";
  output Real i_b(unit = "A", start = K_current * i_b_start / (K_current + R), fixed = true) "Current of phase B";
  output Real v_a(unit = "V") "Voltage applied to phase A";
  output Real v_b(unit = "V") "Voltage applied to phase B";
  output Real power(unit = "W") "Electrical power drawn by both phases";
equation
  v_a = min(max(K_current * (i_a_ref - i_a), -V_supply), V_supply);
  v_b = min(max(K_current * (i_b_ref - i_b), -V_supply), V_supply);
  L * der(i_a) = v_a - R * i_a + k_e * omega * sin(N_c * theta);  // [paper], eq. 7
  L * der(i_b) = v_b - R * i_b + k_e * omega * cos(N_c * theta);  // [paper], eq. 8
  // [paper], eq. 9 with the Simscape block's iron-loss and detent terms (0 with G_m = T_d = 0)
  tau = -k_e * (i_a + G_m * k_e * omega * sin(N_c * theta)) * sin(N_c * theta)
    - k_e * (i_b + G_m * k_e * omega * cos(N_c * theta)) * cos(N_c * theta) - T_d * sin(4 * N_c * theta);
  power = v_a * i_a + v_b * i_b;
end StepperMotor;

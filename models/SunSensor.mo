model SunSensor
  "Differential two-cell sun sensor on the mirror (one axis): signal (A - B)/(A + B), linear in tan(e) in its field of view"
  // A slit (or shadow band) of width w at height h above two cells side by side, their split line
  // under the slit's middle. Sunlight at angle e from the sensor's axis lights a stripe of width w
  // shifted by h tan(e) across the split, so the share of the stripe on cell A is
  //   a = (w/2 + h tan(e))/w = 0.5 + 0.5 tan(e)/tan(fov),  tan(fov) = w/(2 h),
  // while the stripe straddles the split (|e| <= fov), 1 or 0 once it lies on one cell: the linear
  // range is +-fov and the signal saturates outside it. Here the angle is clamped to +-fov before
  // its tangent, the same a as clamping a to [0, 1] for |e| < 90 deg, and still saturated with the
  // sign of e beyond 90 deg (a panel far off, where tan(e) would turn over). Each cell also sees a
  // share diffuse_view of the diffuse irradiance, which dilutes the difference:
  //   A = dni a + diffuse_view dhi,  B = dni (1 - a) + diffuse_view dhi.
  // The aperture's cos(e) on the direct beam is left out (it scales both cells alike; near balance
  // it is 1). e = k_ray (theta_ref - theta_p + offset): positive when the panel lags the tracking law,
  // and so is the signal, so a controller stepping toward a positive signal closes the loop.
  // Sources and bands: docs/physics.md, "The sun sensor"; presets: heliostep/data/sun_sensors.yaml.
  // k_ray: a sensor sighting the mirror's reflected ray against the receiver's direction reads
  // 2 (theta_ref - theta_p): a mirror turning by x turns its reflected ray by 2x, and the ray meets
  // the receiver exactly at the tracking law, whatever the sun's position (the normal bisects sun
  // and receiver). A sensor that sights the sun directly from a fixed mount on a linear Fresnel
  // mirror reads theta_ref - theta_p plus half the angle between the sun and the receiver (less its
  // mount's angle), a zero that moves through the day: so 2 fits the linear Fresnel mirror (1 is a
  // collector that faces the sun, as seed 001's).
  parameter Real k_ray(unit = "1") = 2 "Sensor angle per panel angle: 2 sighting the reflected ray (linear Fresnel mirror)";
  // fov: Solar MEMS, SSOC-D60 Technical specification (Doc. SSOCD60-14-MAN-119 rev. 1.19), page 1,
  // Specifications: field of view +-60 deg.
  parameter Real fov(unit = "rad", min = 0, max = 1.5) = 1.0471975511965976 "Half field of view of the linear range, +-60 deg (Solar MEMS SSOC-D60 datasheet)";
  // offset: a mounting (or calibration) error, none by default; the datasheet's accuracy 0.3 deg is
  // its band (docs/physics.md). The closed loop tracks to theta_ref + offset.
  parameter Real offset(unit = "rad") = 0 "Mounting offset added to the pointing error (a fault; none by default)";
  // threshold: the datasheet gives none. WMO's sunshine threshold: direct normal irradiance above
  // 120 W/m2 counts as sunshine (WMO Guide to Instruments and Methods of Observation, WMO-No. 8,
  // chapter on sunshine duration). Assumed for A + B; band 50-300 W/m2 (docs/physics.md).
  parameter Real threshold(unit = "W/m2", min = 0) = 120 "Dark threshold on A + B (assumed: WMO sunshine threshold, 120 W/m2)";
  // diffuse_view: under an isotropic sky (Liu and Jordan) an aperture passes the share of the
  // diffuse horizontal irradiance that its acceptance cone projects onto the unit disk: a square
  // window accepting +-fov on both axes (the SSOC-D60's four-quadrant cell) passes
  // (4/pi) sin(fov) atan(sin(fov)), a slit accepting +-fov across (all angles along) sin(fov);
  // half of it falls on each cell: (2/pi) sin(60 deg) atan(sin(60 deg)) = 0.393. Assumed: sensor
  // facing up, isotropic sky (band in docs/physics.md).
  parameter Real diffuse_view(unit = "1", min = 0) = 0.3934968734792222 "Share of the diffuse irradiance each cell sees (isotropic sky through a +-fov window)";
  input Real theta_p(unit = "rad") "Panel angle";
  input Real theta_ref(unit = "rad") "Panel angle of ideal tracking at this instant (the tracking law)";
  input Real dni(unit = "W/m2") "Direct normal irradiance";
  input Real dhi(unit = "W/m2") "Diffuse horizontal irradiance";
  input Real noise(unit = "1") "Additive noise on the signal (supplied by the master)";
  output Real signal(unit = "1") "(A - B)/(A + B) + noise; 0 in the dark";
  output Real irradiance(unit = "W/m2") "A + B, the irradiance both cells see";
  output Real lit(unit = "1") "1 when A + B is above the dark threshold, else 0";
  Real e(unit = "rad") "Sensor angle error k_ray (theta_ref - theta_p + offset)";
  Real a(unit = "1") "Share of the direct beam on cell A";
equation
  e = k_ray * (theta_ref - theta_p + offset);
  a = 0.5 + 0.5 * tan(min(max(e, -fov), fov)) / tan(fov);
  irradiance = dni + 2 * diffuse_view * dhi;  // A + B
  lit = if irradiance > threshold then 1 else 0;
  // A - B = dni (2 a - 1); in the dark branch the quotient is not used (max keeps it finite)
  signal = if irradiance > threshold then dni * (2 * a - 1) / max(irradiance, threshold) + noise else 0;
end SunSensor;

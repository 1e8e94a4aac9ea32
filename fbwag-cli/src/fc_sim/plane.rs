//! A kinematic fixed-wing model for `fbwag fc-sim`'s telemetry: enough
//! flight for a ground station's map, not an aerodynamic simulation.
//!
//! The aircraft is a point with a heading, an airspeed and a climb rate in
//! still air (groundspeed = airspeed). Bank gives the turn rate of a
//! coordinated turn, `rate = g·tan(bank)/v`; throttle moves the airspeed and
//! the climb a little; every state follows its target with a first-order
//! lag. Position is kept in metres north and east of home on a flat earth
//! (good to a few metres over the tens of kilometres a bench run covers)
//! and converted to latitude and longitude on output.
//!
//! What flies the model is a [`Guidance`]: sticks (the pilot's, or the
//! companion's applied control in FBWAG), a constant-bank turn (CIRCLE), or
//! back to home and a loiter around it (RTL). The model advances in fixed
//! 20 ms steps of its own time, so its path depends only on the guidance and
//! the times at which it changed: deterministic.

use std::f64::consts::{PI, TAU};

/// Standard gravity (m/s²).
const G: f64 = 9.80665;
/// Mean earth radius (m), for the flat-earth conversion.
const EARTH_RADIUS: f64 = 6_371_000.0;
/// The model's fixed step (s).
pub const STEP: f64 = 0.02;
/// Airspeed at trim throttle (m/s), until AIRSPEED_CRUISE says otherwise.
pub const CRUISE_AIRSPEED: f64 = 18.0;
/// Airspeed limits (m/s): ArduPlane's AIRSPEED_MIN/MAX defaults, roughly.
const MIN_AIRSPEED: f64 = 12.0;
const MAX_AIRSPEED: f64 = 30.0;
/// Throttle (0..1) that holds cruise airspeed and altitude (ArduPlane's
/// TRIM_THROTTLE, 45 %).
pub const TRIM_THROTTLE: f64 = 0.45;
/// Airspeed and climb gained per unit of throttle above trim.
const SPEED_PER_THROTTLE: f64 = 10.0;
const CLIMB_PER_THROTTLE: f64 = 2.0;
/// Bank at full roll stick (ArduPlane's ROLL_LIMIT_DEG default, 45°).
const MAX_BANK: f64 = 45.0 * PI / 180.0;
/// Bank the navigation modes use at most (RTL's turn toward home).
const NAV_BANK: f64 = 30.0 * PI / 180.0;
/// CIRCLE's constant bank: a gentle turn.
pub const CIRCLE_BANK: f64 = 15.0 * PI / 180.0;
/// Climb or sink at full pitch stick (TECS_CLMB_MAX, TECS_SINK_MAX: 5 m/s).
const MAX_CLIMB: f64 = 5.0;
/// RTL: height over home it returns at (ArduPlane's RTL altitude, 100 m),
/// and the loiter radius around home (WP_LOITER_RAD, 60 m).
pub const RTL_HEIGHT: f64 = 100.0;
pub const LOITER_RADIUS: f64 = 60.0;
/// Where a run starts: over home at this height, heading north.
pub const START_HEIGHT: f64 = 100.0;
/// Time constants (s) of bank, airspeed and climb.
const BANK_TAU: f64 = 0.5;
const SPEED_TAU: f64 = 3.0;
const CLIMB_TAU: f64 = 1.0;
/// Angle of attack added to the flight-path angle for the pitch shown.
const CRUISE_AOA: f64 = 0.03;

/// Where home is: the ground under the start, altitude above mean sea level.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Home {
    /// Degrees, −90..90.
    pub lat_deg: f64,
    /// Degrees, −180..180.
    pub lon_deg: f64,
    /// Metres above mean sea level.
    pub alt_m: f64,
}

impl Home {
    /// ArduPilot SITL's default home (CMAC, Canberra).
    pub const DEFAULT: Home = Home {
        lat_deg: -35.363261,
        lon_deg: 149.165230,
        alt_m: 584.0,
    };
}

/// Why a `--home` value was refused.
#[derive(Debug, Clone, PartialEq)]
pub enum HomeError {
    /// Not three comma-separated numbers.
    Format(String),
    /// A number outside its range (or not finite).
    Range(&'static str),
}

impl std::fmt::Display for HomeError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            HomeError::Format(s) => write!(
                f,
                "expected LAT,LON,ALT (degrees, degrees, metres above sea level), got {s:?}"
            ),
            HomeError::Range(what) => write!(
                f,
                "{what} out of range (latitude -89..89, longitude -180..180, altitude -500..9000 m)"
            ),
        }
    }
}

impl std::error::Error for HomeError {}

impl std::str::FromStr for Home {
    type Err = HomeError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let parts: Vec<f64> = s
            .split(',')
            .map(|p| p.trim().parse::<f64>())
            .collect::<Result<_, _>>()
            .map_err(|_| HomeError::Format(s.into()))?;
        let [lat, lon, alt] = parts[..] else {
            return Err(HomeError::Format(s.into()));
        };
        // Near the poles the flat-earth conversion divides by cos(lat).
        if !(lat.is_finite() && lat.abs() <= 89.0) {
            return Err(HomeError::Range("latitude"));
        }
        if !(lon.is_finite() && lon.abs() <= 180.0) {
            return Err(HomeError::Range("longitude"));
        }
        if !(alt.is_finite() && (-500.0..=9000.0).contains(&alt)) {
            return Err(HomeError::Range("altitude"));
        }
        Ok(Home {
            lat_deg: lat,
            lon_deg: lon,
            alt_m: alt,
        })
    }
}

/// Stick positions: roll and pitch −1..1 (right, nose up positive),
/// throttle 0..1.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sticks {
    pub roll: f64,
    pub pitch: f64,
    pub throttle: f64,
}

impl Sticks {
    /// Centred sticks at trim throttle: straight and level.
    #[cfg(test)]
    pub const NEUTRAL: Sticks = Sticks {
        roll: 0.0,
        pitch: 0.0,
        throttle: TRIM_THROTTLE,
    };

    /// Sticks from RC channels 1–4 (aileron, elevator, throttle, rudder;
    /// 1000–2000 µs). A channel of 0 or 65535 ("no change" in an override)
    /// leaves that axis at neutral.
    pub fn from_channels(ch: &[u16; 8]) -> Sticks {
        let set = |c: u16| c != 0 && c != u16::MAX;
        let axis = |c: u16| {
            if set(c) {
                ((f64::from(c) - 1500.0) / 500.0).clamp(-1.0, 1.0)
            } else {
                0.0
            }
        };
        let throttle = if set(ch[2]) {
            ((f64::from(ch[2]) - 1000.0) / 1000.0).clamp(0.0, 1.0)
        } else {
            TRIM_THROTTLE
        };
        Sticks {
            roll: axis(ch[0]),
            pitch: axis(ch[1]),
            throttle,
        }
    }
}

/// What flies the model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Guidance {
    /// Stabilised stick flying (FBWA-like): bank and climb follow the sticks.
    Sticks(Sticks),
    /// A constant-bank turn to the right at constant height (CIRCLE).
    Circle,
    /// Fly to home at the RTL height, then loiter around it (RTL).
    ReturnHome,
}

/// The aircraft's state.
#[derive(Debug, Clone, PartialEq)]
pub struct Plane {
    home: Home,
    /// Seconds of model time.
    t: f64,
    north: f64,
    east: f64,
    /// Height above home (m).
    height: f64,
    /// Heading, radians clockwise from north, 0..2π.
    heading: f64,
    airspeed: f64,
    /// Airspeed at trim throttle (AIRSPEED_CRUISE).
    cruise: f64,
    climb: f64,
    bank: f64,
    throttle: f64,
    /// Turn rate (rad/s) and bank rate, for ATTITUDE's body rates.
    yaw_rate: f64,
    roll_rate: f64,
}

/// What telemetry reports of the model at one moment.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Snapshot {
    pub lat_deg: f64,
    pub lon_deg: f64,
    /// Metres above mean sea level.
    pub alt_m: f64,
    /// Metres above home.
    pub height_m: f64,
    /// Radians clockwise from north, 0..2π.
    pub heading: f64,
    pub airspeed: f64,
    pub groundspeed: f64,
    /// m/s, up positive.
    pub climb: f64,
    /// Velocity north and east (m/s).
    pub v_north: f64,
    pub v_east: f64,
    pub roll: f64,
    pub pitch: f64,
    pub roll_rate: f64,
    pub yaw_rate: f64,
    /// 0..1.
    pub throttle: f64,
}

impl Plane {
    /// Over `home` at [`START_HEIGHT`], heading north at cruise airspeed.
    pub fn new(home: Home) -> Self {
        Plane {
            home,
            t: 0.0,
            north: 0.0,
            east: 0.0,
            height: START_HEIGHT,
            heading: 0.0,
            airspeed: CRUISE_AIRSPEED,
            cruise: CRUISE_AIRSPEED,
            climb: 0.0,
            bank: 0.0,
            throttle: TRIM_THROTTLE,
            yaw_rate: 0.0,
            roll_rate: 0.0,
        }
    }

    pub fn home(&self) -> Home {
        self.home
    }

    /// The airspeed flown at trim throttle from now on (m/s, within the
    /// airspeed limits).
    pub fn set_cruise_airspeed(&mut self, airspeed: f64) {
        self.cruise = airspeed.clamp(MIN_AIRSPEED, MAX_AIRSPEED);
    }

    /// Advances in whole steps up to time `t` (s) under `guidance`; a time
    /// not after the model's own does nothing.
    pub fn advance_to(&mut self, t: f64, guidance: Guidance) {
        // A bounded number of steps per call: a stalled caller catches up
        // over later calls instead of spinning here (one hour of flight).
        let mut budget = 180_000u32;
        while self.t + STEP <= t && budget > 0 {
            self.step(guidance);
            budget -= 1;
        }
    }

    /// One fixed step.
    fn step(&mut self, guidance: Guidance) {
        let (bank, climb, throttle) = self.targets(guidance);
        let lag = |tau: f64| (STEP / tau).min(1.0);
        let bank_before = self.bank;
        self.bank += (bank - self.bank) * lag(BANK_TAU);
        self.roll_rate = (self.bank - bank_before) / STEP;
        self.throttle = throttle;
        let speed = self.cruise + (throttle - TRIM_THROTTLE) * SPEED_PER_THROTTLE;
        let speed = speed.clamp(MIN_AIRSPEED, MAX_AIRSPEED);
        self.airspeed += (speed - self.airspeed) * lag(SPEED_TAU);
        self.climb += (climb - self.climb) * lag(CLIMB_TAU);
        self.yaw_rate = G * self.bank.tan() / self.airspeed;
        self.heading = (self.heading + self.yaw_rate * STEP).rem_euclid(TAU);
        let horizontal = self.horizontal_speed();
        self.north += horizontal * self.heading.cos() * STEP;
        self.east += horizontal * self.heading.sin() * STEP;
        self.height += self.climb * STEP;
        if self.height < 0.0 {
            // The ground: a bench model does not crash, it skims.
            self.height = 0.0;
            self.climb = self.climb.max(0.0);
        }
        self.t += STEP;
    }

    /// Speed over the ground in still air: the airspeed's horizontal part.
    fn horizontal_speed(&self) -> f64 {
        let gamma = (self.climb / self.airspeed).clamp(-1.0, 1.0).asin();
        self.airspeed * gamma.cos()
    }

    /// Bank, climb and throttle the guidance asks for now.
    fn targets(&self, guidance: Guidance) -> (f64, f64, f64) {
        match guidance {
            Guidance::Sticks(s) => {
                let climb = s.pitch * MAX_CLIMB + (s.throttle - TRIM_THROTTLE) * CLIMB_PER_THROTTLE;
                (s.roll * MAX_BANK, climb, s.throttle)
            }
            Guidance::Circle => (CIRCLE_BANK, 0.0, TRIM_THROTTLE),
            Guidance::ReturnHome => (self.rtl_bank(), self.rtl_climb(), TRIM_THROTTLE),
        }
    }

    /// RTL's bank: toward home while far, then onto a clockwise circle of
    /// [`LOITER_RADIUS`] around it (the course bends from "at home" to
    /// "tangent" as the aircraft comes within a few radii, and points a
    /// little outward inside the circle).
    fn rtl_bank(&self) -> f64 {
        let distance = self.north.hypot(self.east);
        let to_home = (-self.east).atan2(-self.north);
        let offset = if distance < 1e-6 {
            PI / 2.0
        } else {
            (PI / 2.0 * LOITER_RADIUS / distance).min(2.0 * PI / 3.0)
        };
        let course = to_home + offset;
        let error = (course - self.heading + PI).rem_euclid(TAU) - PI;
        (1.5 * error).clamp(-NAV_BANK, NAV_BANK)
    }

    /// RTL's climb toward [`RTL_HEIGHT`], at most 3 m/s either way.
    fn rtl_climb(&self) -> f64 {
        ((RTL_HEIGHT - self.height) * 0.2).clamp(-3.0, 3.0)
    }

    /// Distance from home (m, horizontal).
    #[cfg(test)]
    pub fn distance_from_home(&self) -> f64 {
        self.north.hypot(self.east)
    }

    /// The state as telemetry reports it.
    pub fn snapshot(&self) -> Snapshot {
        let lat = self.home.lat_deg + (self.north / EARTH_RADIUS).to_degrees();
        let lon = self.home.lon_deg
            + (self.east / (EARTH_RADIUS * self.home.lat_deg.to_radians().cos())).to_degrees();
        let horizontal = self.horizontal_speed();
        let gamma = (self.climb / self.airspeed).clamp(-1.0, 1.0).asin();
        Snapshot {
            lat_deg: lat,
            lon_deg: (lon + 180.0).rem_euclid(360.0) - 180.0,
            alt_m: self.home.alt_m + self.height,
            height_m: self.height,
            heading: self.heading,
            airspeed: self.airspeed,
            groundspeed: horizontal,
            climb: self.climb,
            v_north: horizontal * self.heading.cos(),
            v_east: horizontal * self.heading.sin(),
            roll: self.bank,
            pitch: gamma + CRUISE_AOA,
            roll_rate: self.roll_rate,
            yaw_rate: self.yaw_rate,
            throttle: self.throttle,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fly(guidance: Guidance, seconds: f64) -> Plane {
        let mut p = Plane::new(Home::DEFAULT);
        p.advance_to(seconds, guidance);
        p
    }

    #[test]
    fn starts_over_home_heading_north() {
        let s = Plane::new(Home::DEFAULT).snapshot();
        assert_eq!((s.lat_deg, s.lon_deg), (-35.363261, 149.165230));
        assert_eq!(s.alt_m, 584.0 + START_HEIGHT);
        assert_eq!(s.heading, 0.0);
    }

    #[test]
    fn neutral_sticks_fly_straight_and_level() {
        let p = fly(Guidance::Sticks(Sticks::NEUTRAL), 10.0);
        let s = p.snapshot();
        assert!((p.distance_from_home() - 180.0).abs() < 1.0, "{p:?}");
        assert!(s.heading.abs() < 1e-9 && (s.height_m - START_HEIGHT).abs() < 1e-9);
        // North of home: latitude grew (southern hemisphere: less negative).
        assert!(s.lat_deg > -35.363261);
    }

    #[test]
    fn bank_turns_at_the_coordinated_rate() {
        // Full right stick: 45° of bank, so g·tan(45°)/v ≈ 0.545 rad/s at 18 m/s.
        let sticks = Sticks {
            roll: 1.0,
            ..Sticks::NEUTRAL
        };
        let s = fly(Guidance::Sticks(sticks), 5.0).snapshot();
        assert!((s.roll - MAX_BANK).abs() < 1e-3);
        assert!((s.yaw_rate - G / s.airspeed).abs() < 1e-3, "{s:?}");
    }

    #[test]
    fn throttle_changes_speed_and_climb() {
        let full = Sticks {
            throttle: 1.0,
            ..Sticks::NEUTRAL
        };
        let s = fly(Guidance::Sticks(full), 20.0).snapshot();
        assert!(s.airspeed > CRUISE_AIRSPEED + 4.0 && s.climb > 0.9, "{s:?}");
        let idle = Sticks {
            throttle: 0.0,
            ..Sticks::NEUTRAL
        };
        let s = fly(Guidance::Sticks(idle), 20.0).snapshot();
        assert!(
            s.airspeed < CRUISE_AIRSPEED - 3.0 && s.climb < -0.8,
            "{s:?}"
        );
    }

    #[test]
    fn circle_turns_right_at_constant_height() {
        let p = fly(Guidance::Circle, 60.0);
        let s = p.snapshot();
        assert!((s.roll - CIRCLE_BANK).abs() < 1e-6 && s.yaw_rate > 0.1);
        assert!((s.height_m - START_HEIGHT).abs() < 1e-9);
        // A circle of radius v²/(g·tan 15°) ≈ 123 m: never far from the start.
        assert!(p.distance_from_home() < 260.0, "{p:?}");
    }

    #[test]
    fn rtl_comes_back_and_loiters_around_home() {
        let mut p = Plane::new(Home::DEFAULT);
        p.advance_to(60.0, Guidance::Sticks(Sticks::NEUTRAL));
        let away = p.distance_from_home();
        assert!(away > 1000.0);
        // Turning round takes a few seconds; then the distance falls.
        p.advance_to(70.0, Guidance::ReturnHome);
        let d70 = p.distance_from_home();
        p.advance_to(80.0, Guidance::ReturnHome);
        assert!(p.distance_from_home() < d70 - 150.0, "{p:?}");
        // Long after: loitering near the loiter radius.
        p.advance_to(300.0, Guidance::ReturnHome);
        let mut worst: f64 = 0.0;
        for k in 0..60 {
            p.advance_to(300.0 + f64::from(k), Guidance::ReturnHome);
            worst = worst.max((p.distance_from_home() - LOITER_RADIUS).abs());
        }
        assert!(worst < 40.0, "{worst} {p:?}");
        assert!((p.snapshot().height_m - RTL_HEIGHT).abs() < 1.0);
    }

    #[test]
    fn deterministic_and_step_aligned() {
        let g = Guidance::Sticks(Sticks {
            roll: 0.3,
            pitch: 0.1,
            throttle: 0.6,
        });
        let mut a = Plane::new(Home::DEFAULT);
        a.advance_to(12.345, g);
        let mut b = Plane::new(Home::DEFAULT);
        for k in 0..=12345 {
            b.advance_to(f64::from(k) / 1000.0, g);
        }
        assert_eq!(a, b);
    }

    #[test]
    fn channels_map_to_sticks() {
        let s = Sticks::from_channels(&[2000, 1000, 1600, 1500, 0, 0, 0, 0]);
        assert_eq!((s.roll, s.pitch), (1.0, -1.0));
        assert!((s.throttle - 0.6).abs() < 1e-12);
        // "No change" channels are neutral.
        let s = Sticks::from_channels(&[0, u16::MAX, 0, 0, 0, 0, 0, 0]);
        assert_eq!(s, Sticks::NEUTRAL);
        // Out-of-range values are clamped.
        let s = Sticks::from_channels(&[9000, 10, 3000, 0, 0, 0, 0, 0]);
        assert_eq!((s.roll, s.pitch, s.throttle), (1.0, -1.0, 1.0));
    }

    #[test]
    fn home_parses_and_refuses() {
        let h: Home = "50.45, 30.52, 180".parse().unwrap();
        assert_eq!((h.lat_deg, h.lon_deg, h.alt_m), (50.45, 30.52, 180.0));
        for bad in [
            "", "1,2", "1,2,3,4", "a,b,c", "95,0,0", "0,200,0", "0,0,NaN",
        ] {
            assert!(bad.parse::<Home>().is_err(), "{bad}");
        }
    }
}

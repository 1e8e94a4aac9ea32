//! `fbwag fc-sim`'s parameters: the failsafe settings of the delegation
//! protocol, named as ArduPlane names them where ArduPlane has the setting
//! (FS_*, SYSID_THISMAV) and `FBWAG_*` where it has none, and the model's
//! cruise airspeed (AIRSPEED_CRUISE), an ordinary parameter.
//!
//! Every value is read from, and written into, the [`Settings`] in force:
//! the FC engine's [`FcConfig`] and the model's airspeed; there is no
//! second copy to drift. A write is checked here (type, range, the
//! engine's own [`FcConfig::validate`]) and gives the new settings; when
//! it may take effect is the daemon's decision: the parameters that decide
//! who flies ([`fbwag_delegation::protected`]) only while disarmed and
//! with the pilot flying (changing timeouts or the trusted companion in
//! the middle of a flight or a handover could end it), the others at any
//! time. Values travel as ArduPilot sends them: C-cast into PARAM_VALUE's
//! float (MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_C_CAST).

use fbwag_delegation::fc::FcConfig;
use fbwag_delegation::{ConfigError, Peer};
use fbwag_dialect::dialects::common::MavParamType;
use std::fmt;
use std::time::Duration;

/// ArduPlane's FS_SHORT_ACTN value for the paper's new short-failsafe
/// action: delegate to the companion (FBWAG).
pub const FS_SHORT_ACTN_FBWAG: f32 = 5.0;
/// ArduPlane's FS_LONG_ACTN value for RTL, the protocol's fallback.
pub const FS_LONG_ACTN_RTL: f32 = 1.0;

/// What the parameters read and write.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Settings {
    /// The FC engine's.
    pub fc: FcConfig,
    /// The model's airspeed at trim throttle (m/s).
    pub cruise_airspeed: f32,
}

/// One parameter.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Param {
    /// Short-failsafe action: 5 (FBWAG, the paper's new value). Fixed:
    /// fc-sim always delegates.
    FsShortActn,
    /// Seconds of receiver loss before the short failsafe: the engine's
    /// `rc_loss_samples` at the 10 Hz RC check.
    FsShortTimeout,
    /// Long-failsafe action: 1 (RTL). Fixed: the protocol's fallback.
    FsLongActn,
    /// Seconds from the first notice to RTL when the companion has not
    /// acknowledged: the engine's `handshake_timeout` (the long failsafe of
    /// the delegation; it never ends companion control once taken).
    FsLongTimeout,
    /// This FC's system id; read only (a restart with --sysid changes it).
    SysidThismav,
    /// The companion allowed to take over: system id.
    CcSysid,
    /// The companion allowed to take over: component id.
    CcCompid,
    /// Seconds between notices of one event (`retry_interval`).
    RetryTime,
    /// Notices repeated after the first (`max_retries`).
    RetryMax,
    /// Seconds without an override that end companion control
    /// (`override_timeout`); below ArduPlane's RC_OVERRIDE_TIME (3 s).
    OvrdTime,
    /// Seconds of companion silence that end companion control
    /// (`heartbeat_timeout`).
    CcTimeout,
    /// 1 when only signed frames count; read only (--require-signed).
    Signed,
    /// The airspeed the model flies at trim throttle (m/s); ArduPlane's
    /// name since 4.5. Not protected: writable in flight.
    AirspeedCruise,
}

impl Param {
    /// All parameters, in index order.
    pub const ALL: [Param; 13] = [
        Param::FsShortActn,
        Param::FsShortTimeout,
        Param::FsLongActn,
        Param::FsLongTimeout,
        Param::SysidThismav,
        Param::CcSysid,
        Param::CcCompid,
        Param::RetryTime,
        Param::RetryMax,
        Param::OvrdTime,
        Param::CcTimeout,
        Param::Signed,
        Param::AirspeedCruise,
    ];

    /// The name on the wire (at most 16 characters).
    pub fn name(self) -> &'static str {
        match self {
            Param::FsShortActn => "FS_SHORT_ACTN",
            Param::FsShortTimeout => "FS_SHORT_TIMEOUT",
            Param::FsLongActn => "FS_LONG_ACTN",
            Param::FsLongTimeout => "FS_LONG_TIMEOUT",
            Param::SysidThismav => "SYSID_THISMAV",
            Param::CcSysid => "FBWAG_CC_SYSID",
            Param::CcCompid => "FBWAG_CC_COMPID",
            Param::RetryTime => "FBWAG_RETRY_TIME",
            Param::RetryMax => "FBWAG_RETRY_MAX",
            Param::OvrdTime => "FBWAG_OVRD_TIME",
            Param::CcTimeout => "FBWAG_CC_TIMEOUT",
            Param::Signed => "FBWAG_SIGNED",
            Param::AirspeedCruise => "AIRSPEED_CRUISE",
        }
    }

    /// The type announced in PARAM_VALUE (ArduPlane's for its own names).
    pub fn param_type(self) -> MavParamType {
        match self {
            Param::FsShortActn | Param::FsLongActn | Param::Signed => MavParamType::INT8,
            Param::SysidThismav | Param::CcSysid | Param::CcCompid | Param::RetryMax => {
                MavParamType::INT16
            }
            Param::FsShortTimeout
            | Param::FsLongTimeout
            | Param::RetryTime
            | Param::OvrdTime
            | Param::CcTimeout
            | Param::AirspeedCruise => MavParamType::REAL32,
        }
    }

    /// Position in [`Param::ALL`].
    pub fn index(self) -> u16 {
        Param::ALL.iter().position(|&p| p == self).unwrap_or(0) as u16
    }

    pub fn by_index(index: i64) -> Option<Param> {
        usize::try_from(index)
            .ok()
            .and_then(|i| Param::ALL.get(i).copied())
    }

    /// By a PARAM_* message's `param_id`: NUL-terminated unless 16 long.
    pub fn by_id(id: &[u8; 16]) -> Option<Param> {
        let end = id.iter().position(|&b| b == 0).unwrap_or(id.len());
        Param::ALL
            .into_iter()
            .find(|p| p.name().as_bytes() == &id[..end])
    }

    /// Whether it decides who flies: writable only while disarmed
    /// ([`fbwag_delegation::protected::is_protected_parameter`]).
    pub fn is_protected(self) -> bool {
        fbwag_delegation::protected::is_protected_parameter(self.name().as_bytes())
    }

    /// The value now, as sent.
    pub fn value(self, settings: &Settings) -> f32 {
        let secs = |d: Duration| d.as_secs_f32();
        let cfg = &settings.fc;
        match self {
            Param::FsShortActn => FS_SHORT_ACTN_FBWAG,
            Param::FsShortTimeout => secs(cfg.rc_sample_period) * f32::from(cfg.rc_loss_samples),
            Param::FsLongActn => FS_LONG_ACTN_RTL,
            Param::FsLongTimeout => secs(cfg.handshake_timeout),
            Param::SysidThismav => f32::from(cfg.own.sysid),
            Param::CcSysid => f32::from(cfg.companion.sysid),
            Param::CcCompid => f32::from(cfg.companion.compid),
            Param::RetryTime => secs(cfg.retry_interval),
            Param::RetryMax => f32::from(cfg.max_retries),
            Param::OvrdTime => secs(cfg.override_timeout),
            Param::CcTimeout => secs(cfg.heartbeat_timeout),
            Param::Signed => f32::from(u8::from(cfg.require_signed)),
            Param::AirspeedCruise => settings.cruise_airspeed,
        }
    }

    /// The settings with this parameter set to `value`, or why not.
    pub fn apply(self, value: f32, settings: &Settings) -> Result<Settings, ParamError> {
        if !value.is_finite() {
            return Err(ParamError::NotFinite(self));
        }
        if self == Param::AirspeedCruise {
            let cruise_airspeed = range(self, value, 12.0, 30.0)?;
            return Ok(Settings {
                cruise_airspeed,
                ..*settings
            });
        }
        let cfg = &settings.fc;
        let mut new = *cfg;
        match self {
            Param::FsShortActn => fixed(self, value, FS_SHORT_ACTN_FBWAG, "always 5 (FBWAG)")?,
            Param::FsLongActn => fixed(self, value, FS_LONG_ACTN_RTL, "always 1 (RTL)")?,
            Param::SysidThismav => {
                fixed(self, value, self.value(settings), "restart with --sysid")?
            }
            Param::Signed => fixed(
                self,
                value,
                self.value(settings),
                "start with --require-signed",
            )?,
            Param::FsShortTimeout => {
                let period = cfg.rc_sample_period.as_secs_f32();
                let samples = range(self, value / period, 1.0, 255.0)?;
                new.rc_loss_samples = samples.round() as u8;
            }
            Param::FsLongTimeout => new.handshake_timeout = seconds(self, value, 0.5, 300.0)?,
            Param::CcSysid => new.companion = Peer::new(id(self, value)?, cfg.companion.compid),
            Param::CcCompid => new.companion = Peer::new(cfg.companion.sysid, id(self, value)?),
            Param::RetryTime => new.retry_interval = seconds(self, value, 0.1, 10.0)?,
            Param::RetryMax => new.max_retries = integer(self, value, 0.0, 255.0)? as u8,
            Param::OvrdTime => new.override_timeout = seconds(self, value, 0.1, 2.9)?,
            Param::CcTimeout => new.heartbeat_timeout = seconds(self, value, 0.5, 60.0)?,
            Param::AirspeedCruise => {}
        }
        new.validate().map_err(|e| ParamError::Config(self, e))?;
        Ok(Settings {
            fc: new,
            ..*settings
        })
    }
}

/// Why a parameter was not set.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ParamError {
    /// NaN or infinite.
    NotFinite(Param),
    /// This parameter has one value in fc-sim; the text says which or how
    /// to change it.
    Fixed(Param, &'static str),
    /// A whole number was expected.
    NotInteger(Param),
    /// Outside min..=max.
    Range(Param, f32, f32),
    /// The engine refuses the resulting configuration.
    Config(Param, ConfigError),
    /// Not while a handover is under way or the receiver is lost: the
    /// flight mode now.
    Busy(Param, &'static str),
    /// It decides who flies: not while armed.
    Armed(Param),
}

impl fmt::Display for ParamError {
    // Short: the text goes into a 50-character STATUSTEXT.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ParamError::NotFinite(p) => write!(f, "{}: not a number", p.name()),
            ParamError::Fixed(p, why) => write!(f, "{}: {why}", p.name()),
            ParamError::NotInteger(p) => write!(f, "{}: whole numbers only", p.name()),
            ParamError::Range(p, lo, hi) => write!(f, "{}: {lo}..{hi} only", p.name()),
            ParamError::Config(p, e) => write!(f, "{}: {e}", p.name()),
            ParamError::Busy(p, mode) => write!(f, "{}: not in {mode}, pilot only", p.name()),
            ParamError::Armed(p) => write!(f, "{}: not while armed", p.name()),
        }
    }
}

impl std::error::Error for ParamError {}

fn fixed(p: Param, value: f32, only: f32, why: &'static str) -> Result<(), ParamError> {
    if value == only {
        Ok(())
    } else {
        Err(ParamError::Fixed(p, why))
    }
}

fn range(p: Param, value: f32, lo: f32, hi: f32) -> Result<f32, ParamError> {
    if (lo..=hi).contains(&value) {
        Ok(value)
    } else {
        Err(ParamError::Range(p, lo, hi))
    }
}

fn integer(p: Param, value: f32, lo: f32, hi: f32) -> Result<f32, ParamError> {
    if value.fract() != 0.0 {
        return Err(ParamError::NotInteger(p));
    }
    range(p, value, lo, hi)
}

/// A system or component id: 1..255 (0 is the broadcast address).
fn id(p: Param, value: f32) -> Result<u8, ParamError> {
    integer(p, value, 1.0, 255.0).map(|v| v as u8)
}

/// Seconds, kept to the millisecond.
fn seconds(p: Param, value: f32, lo: f32, hi: f32) -> Result<Duration, ParamError> {
    let s = range(p, value, lo, hi)?;
    Ok(Duration::from_millis((f64::from(s) * 1000.0).round() as u64))
}

#[cfg(test)]
mod tests {
    use super::*;
    use fbwag_dialect::mavframe::field::chars;

    #[test]
    fn names_fit_and_are_unique() {
        for (i, p) in Param::ALL.iter().enumerate() {
            assert!(p.name().len() <= 16, "{}", p.name());
            assert_eq!(Param::by_id(&chars(p.name())), Some(*p));
            assert_eq!(p.index() as usize, i);
            assert_eq!(Param::by_index(i as i64), Some(*p));
        }
        assert_eq!(Param::by_index(-1), None);
        assert_eq!(Param::by_index(Param::ALL.len() as i64), None);
        assert_eq!(Param::by_id(&chars("FS_SHORT")), None);
        // A 16-character name has no terminator.
        assert_eq!(
            Param::by_id(b"FS_SHORT_TIMEOUT"),
            Some(Param::FsShortTimeout)
        );
    }

    #[test]
    fn defaults_read_as_the_paper_values() {
        let cfg = settings();
        let v = |p: Param| p.value(&cfg);
        assert_eq!(v(Param::FsShortActn), 5.0);
        assert!((v(Param::FsShortTimeout) - 0.2).abs() < 1e-6);
        assert_eq!(v(Param::FsLongTimeout), 5.0);
        assert_eq!(v(Param::CcCompid), 191.0);
        assert_eq!(v(Param::RetryTime), 1.0);
        assert_eq!(v(Param::RetryMax), 3.0);
        assert_eq!(v(Param::OvrdTime), 1.0);
        assert_eq!(v(Param::Signed), 0.0);
        assert_eq!(v(Param::AirspeedCruise), 18.0);
        // Every parameter but the airspeed decides who flies.
        let free: Vec<Param> = Param::ALL
            .into_iter()
            .filter(|p| !p.is_protected())
            .collect();
        assert_eq!(free, [Param::AirspeedCruise]);
    }

    #[test]
    fn writes_change_the_engine_config() {
        let cfg = settings();
        let new = Param::FsShortTimeout.apply(0.5, &cfg).unwrap();
        assert_eq!(new.fc.rc_loss_samples, 5);
        let new = Param::CcSysid.apply(42.0, &cfg).unwrap();
        assert_eq!(new.fc.companion, Peer::new(42, 191));
        let new = Param::FsLongTimeout.apply(7.25, &cfg).unwrap();
        assert_eq!(new.fc.handshake_timeout, Duration::from_millis(7250));
        let new = Param::AirspeedCruise.apply(22.0, &cfg).unwrap();
        assert_eq!((new.cruise_airspeed, new.fc), (22.0, cfg.fc));
        // Writing the one allowed value of a fixed parameter is a no-op.
        assert_eq!(Param::FsShortActn.apply(5.0, &cfg), Ok(cfg));
    }

    #[test]
    fn bad_writes_are_refused_with_a_reason() {
        let cfg = settings();
        let err = |p: Param, v: f32| p.apply(v, &cfg).unwrap_err();
        assert!(matches!(
            err(Param::FsShortActn, 1.0),
            ParamError::Fixed(..)
        ));
        assert!(matches!(
            err(Param::SysidThismav, 2.0),
            ParamError::Fixed(..)
        ));
        assert!(matches!(err(Param::CcSysid, 0.0), ParamError::Range(..)));
        assert!(matches!(
            err(Param::CcSysid, 1.5),
            ParamError::NotInteger(..)
        ));
        assert!(matches!(
            err(Param::RetryTime, f32::NAN),
            ParamError::NotFinite(..)
        ));
        assert!(matches!(err(Param::OvrdTime, 3.0), ParamError::Range(..)));
        // The engine's own rule: its confirmation stream (200 ms) must be
        // faster than the retry period.
        assert!(matches!(
            err(Param::RetryTime, 0.15),
            ParamError::Config(..)
        ));
        assert!(matches!(
            err(Param::AirspeedCruise, 40.0),
            ParamError::Range(..)
        ));
        assert!(err(Param::FsShortActn, 1.0).to_string().len() <= 50);
        assert!(ParamError::Armed(Param::FsShortTimeout).to_string().len() <= 50);
    }

    fn settings() -> Settings {
        Settings {
            fc: FcConfig::default(),
            cruise_airspeed: 18.0,
        }
    }
}

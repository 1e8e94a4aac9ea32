//! The messages `fbwag fc-sim` reports about itself, built from the
//! kinematic model ([`super::plane`]) and the receiver state, as ArduPlane
//! fills them in.

use super::gcs::Stream;
use super::plane::{Plane, Snapshot};
use fbwag_delegation::Peer;
use fbwag_dialect::dialects::common::{
    Attitude, ExtendedSysState, GpsFixType, GpsGlobalOrigin, GpsRawInt, HomePosition,
    MavLandedState, MavSysStatusSensor, MavVtolState, RcChannels, SysStatus, VfrHud,
};
use fbwag_dialect::dialects::standard::{
    AutopilotVersion, FirmwareVersionType, GlobalPositionInt, MavProtocolCapability,
};
use fbwag_dialect::Message;
use std::f64::consts::PI;

/// The state telemetry reports beside the model.
#[derive(Debug, Clone, Copy)]
pub struct Status {
    /// Milliseconds since fc-sim started.
    pub time_boot_ms: u32,
    /// The real receiver delivers frames.
    pub receiver_ok: bool,
    /// RC channels 1–8 in effect: the pilot's, or the applied control's.
    pub channels: [u16; 8],
}

/// The sensors fc-sim has, all working: gyro, accelerometer, compass,
/// barometer, GPS, the RC receiver, the attitude estimate, and the pre-arm
/// checks. No fence (not present, not enabled).
const SENSORS: MavSysStatusSensor = MavSysStatusSensor(
    MavSysStatusSensor::SENSOR_3D_GYRO.0
        | MavSysStatusSensor::SENSOR_3D_ACCEL.0
        | MavSysStatusSensor::SENSOR_3D_MAG.0
        | MavSysStatusSensor::ABSOLUTE_PRESSURE.0
        | MavSysStatusSensor::GPS.0
        | MavSysStatusSensor::RC_RECEIVER.0
        | MavSysStatusSensor::MAV_SYS_STATUS_AHRS.0
        | MavSysStatusSensor::MAV_SYS_STATUS_PREARM_CHECK.0,
);

/// One message of `stream`, now.
pub fn build(stream: Stream, plane: &Plane, status: &Status) -> Message {
    let s = plane.snapshot();
    match stream {
        Stream::Attitude => attitude(&s, status).into(),
        Stream::GlobalPosition => global_position(&s, status).into(),
        Stream::GpsRaw => gps_raw(&s, status).into(),
        Stream::VfrHud => vfr_hud(&s).into(),
        Stream::SysStatus => sys_status(status).into(),
        Stream::RcChannels => rc_channels(status).into(),
        Stream::ExtendedSysState => extended_sys_state().into(),
        Stream::HomePosition => home_position(plane, status).into(),
        Stream::GpsGlobalOrigin => gps_global_origin(plane, status).into(),
    }
}

fn attitude(s: &Snapshot, st: &Status) -> Attitude {
    Attitude {
        time_boot_ms: st.time_boot_ms,
        roll: s.roll as f32,
        pitch: s.pitch as f32,
        // ATTITUDE's yaw is −π..π.
        yaw: ((s.heading + PI).rem_euclid(2.0 * PI) - PI) as f32,
        rollspeed: s.roll_rate as f32,
        pitchspeed: 0.0,
        yawspeed: s.yaw_rate as f32,
    }
}

fn e7(deg: f64) -> i32 {
    (deg * 1e7).round() as i32
}

fn mm(m: f64) -> i32 {
    (m * 1000.0).round() as i32
}

fn centi_degrees(rad: f64) -> u16 {
    ((rad.to_degrees() * 100.0).round() as i64).rem_euclid(36_000) as u16
}

fn cm_per_s(v: f64) -> i16 {
    (v * 100.0).round().clamp(-32768.0, 32767.0) as i16
}

fn global_position(s: &Snapshot, st: &Status) -> GlobalPositionInt {
    GlobalPositionInt {
        time_boot_ms: st.time_boot_ms,
        lat: e7(s.lat_deg),
        lon: e7(s.lon_deg),
        alt: mm(s.alt_m),
        relative_alt: mm(s.height_m),
        vx: cm_per_s(s.v_north),
        vy: cm_per_s(s.v_east),
        // NED: down positive.
        vz: cm_per_s(-s.climb),
        hdg: centi_degrees(s.heading),
    }
}

fn gps_raw(s: &Snapshot, st: &Status) -> GpsRawInt {
    GpsRawInt {
        time_usec: u64::from(st.time_boot_ms) * 1000,
        fix_type: GpsFixType::TYPE_3D_FIX,
        lat: e7(s.lat_deg),
        lon: e7(s.lon_deg),
        alt: mm(s.alt_m),
        // HDOP 0.8, VDOP 1.2; 10 satellites; accuracies in mm and mm/s.
        eph: 80,
        epv: 120,
        vel: (s.groundspeed * 100.0).round() as u16,
        cog: centi_degrees(s.heading),
        satellites_visible: 10,
        alt_ellipsoid: mm(s.alt_m),
        h_acc: 1000,
        v_acc: 1500,
        vel_acc: 300,
        hdg_acc: 0,
        yaw: 0,
    }
}

fn vfr_hud(s: &Snapshot) -> VfrHud {
    VfrHud {
        airspeed: s.airspeed as f32,
        groundspeed: s.groundspeed as f32,
        heading: (centi_degrees(s.heading) / 100) as i16,
        throttle: (s.throttle * 100.0).round() as u16,
        alt: s.alt_m as f32,
        climb: s.climb as f32,
    }
}

/// True health bits: the receiver (and with it the pre-arm checks, as in
/// ArduPlane's RC failsafe) unhealthy while it is lost.
fn sys_status(st: &Status) -> SysStatus {
    let lost =
        MavSysStatusSensor::RC_RECEIVER.0 | MavSysStatusSensor::MAV_SYS_STATUS_PREARM_CHECK.0;
    // The fence's health bit as ArduPilot sets it: healthy unless a fence
    // failed, present or not. (MAVProxy 1.8.75 prints "fence breach" when
    // the bit is clear, whether or not a fence is present.)
    let fence = MavSysStatusSensor::MAV_SYS_STATUS_GEOFENCE.0;
    let health = if st.receiver_ok {
        SENSORS.0 | fence
    } else {
        (SENSORS.0 | fence) & !lost
    };
    SysStatus {
        onboard_control_sensors_present: SENSORS,
        onboard_control_sensors_enabled: SENSORS,
        onboard_control_sensors_health: MavSysStatusSensor(health),
        load: 200,
        voltage_battery: 12_400,
        // −1: current not measured.
        current_battery: -1,
        battery_remaining: 80,
        ..Default::default()
    }
}

fn rc_channels(st: &Status) -> RcChannels {
    let c = st.channels;
    RcChannels {
        time_boot_ms: st.time_boot_ms,
        chancount: 8,
        chan1_raw: c[0],
        chan2_raw: c[1],
        chan3_raw: c[2],
        chan4_raw: c[3],
        chan5_raw: c[4],
        chan6_raw: c[5],
        chan7_raw: c[6],
        chan8_raw: c[7],
        // MAVLink's scale, as ArduPilot sends it: 0..254 is 0..100 %,
        // 255 would mean "unknown".
        rssi: if st.receiver_ok { 254 } else { 0 },
        ..Default::default()
    }
}

/// ArduPlane without a quadplane: not a VTOL (UNDEFINED), flying.
fn extended_sys_state() -> ExtendedSysState {
    ExtendedSysState {
        vtol_state: MavVtolState::UNDEFINED,
        landed_state: MavLandedState::IN_AIR,
    }
}

fn home_position(plane: &Plane, st: &Status) -> HomePosition {
    let home = plane.home();
    HomePosition {
        latitude: e7(home.lat_deg),
        longitude: e7(home.lon_deg),
        altitude: mm(home.alt_m),
        // The local frame's origin is home.
        q: [1.0, 0.0, 0.0, 0.0],
        time_usec: u64::from(st.time_boot_ms) * 1000,
        ..Default::default()
    }
}

/// The origin of the local frame (ArduPilot's EKF origin): home.
fn gps_global_origin(plane: &Plane, st: &Status) -> GpsGlobalOrigin {
    let home = plane.home();
    GpsGlobalOrigin {
        latitude: e7(home.lat_deg),
        longitude: e7(home.lon_deg),
        altitude: mm(home.alt_m),
        time_usec: u64::from(st.time_boot_ms) * 1000,
    }
}

/// What fc-sim can do, as AUTOPILOT_VERSION says: MAVLink 2, parameters
/// C-cast into floats (both the current and the deprecated bit, as
/// ArduPilot sets them), COMMAND_INT, SET_ATTITUDE_TARGET (a control the
/// engine applies in companion control), and the mission protocol with
/// MISSION_ITEM_INT, as far as fc-sim answers it: a download is an empty
/// list, an upload is refused (MAV_MISSION_UNSUPPORTED). MAVSDK downloads
/// nothing from an autopilot without MISSION_INT ("Int messages are not
/// supported"). No fence or rally protocol, no FTP, no position targets.
pub const CAPABILITIES: MavProtocolCapability = MavProtocolCapability(
    MavProtocolCapability::MAVLINK2.0
        | MavProtocolCapability::PARAM_FLOAT.0
        | MavProtocolCapability::PARAM_ENCODE_C_CAST.0
        | MavProtocolCapability::COMMAND_INT.0
        | MavProtocolCapability::SET_ATTITUDE_TARGET.0
        | MavProtocolCapability::MISSION_INT.0,
);

/// The version fc-sim claims: the ArduPlane interface it imitates (4.6, a
/// development build), and "fbwagsim" where ArduPilot puts its git hash, so
/// nobody mistakes it for a real autopilot.
pub fn autopilot_version(own: Peer) -> AutopilotVersion {
    AutopilotVersion {
        capabilities: CAPABILITIES,
        flight_sw_version: (4 << 24) | (6 << 16) | u32::from(FirmwareVersionType::DEV.0),
        flight_custom_version: *b"fbwagsim",
        // Distinct per system id; 0 would mean "no uid".
        uid: 0xFB4A_4700_0000_0000 | u64::from(own.sysid),
        ..Default::default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fc_sim::plane::Home;

    fn status(receiver_ok: bool) -> Status {
        Status {
            time_boot_ms: 1234,
            receiver_ok,
            channels: [1500, 1500, 1450, 1500, 1500, 1500, 1500, 1500],
        }
    }

    #[test]
    fn health_bits_follow_the_receiver() {
        let fence = MavSysStatusSensor::MAV_SYS_STATUS_GEOFENCE.0;
        let ok = sys_status(&status(true));
        assert_eq!(ok.onboard_control_sensors_health.0, SENSORS.0 | fence);
        let lost = sys_status(&status(false));
        let h = lost.onboard_control_sensors_health.0;
        assert_eq!(h & MavSysStatusSensor::RC_RECEIVER.0, 0);
        assert_ne!(h & MavSysStatusSensor::GPS.0, 0);
        // Present and enabled do not change; no fence is claimed, and none
        // has failed.
        assert_eq!(lost.onboard_control_sensors_present, SENSORS);
        assert_eq!(lost.onboard_control_sensors_enabled, SENSORS);
        assert_eq!(SENSORS.0 & fence, 0);
        assert_ne!(h & fence, 0);
        assert_eq!(rc_channels(&status(false)).rssi, 0);
        assert_eq!(rc_channels(&status(true)).rssi, 254);
    }

    #[test]
    fn position_is_home_at_start() {
        let plane = Plane::new(Home::DEFAULT);
        let Message::GlobalPositionInt(p) = build(Stream::GlobalPosition, &plane, &status(true))
        else {
            panic!()
        };
        assert_eq!((p.lat, p.lon), (-353_632_610, 1_491_652_300));
        assert_eq!((p.alt, p.relative_alt), (684_000, 100_000));
        // 18 m/s north.
        assert_eq!((p.vx, p.vy, p.vz, p.hdg), (1800, 0, 0, 0));
        let Message::HomePosition(h) = build(Stream::HomePosition, &plane, &status(true)) else {
            panic!()
        };
        assert_eq!(
            (h.latitude, h.longitude, h.altitude),
            (p.lat, p.lon, 584_000)
        );
    }

    #[test]
    fn headings_wrap() {
        assert_eq!(centi_degrees(2.0 * PI - 1e-9), 0);
        assert_eq!(centi_degrees(PI), 18_000);
        assert_eq!(centi_degrees(-PI / 2.0), 27_000);
    }
}

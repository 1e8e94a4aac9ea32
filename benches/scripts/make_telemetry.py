#!/usr/bin/env python3
"""Write a reproducible, realistic ArduPlane telemetry capture, framed by pymavlink.

A simulated ArduPlane (sysid 1, compid 1) flies left-hand circuits near
Poltava (49.627 N, 34.487 E) in FBWA while streaming what ArduPlane streams to
a GCS at typical SRx_* rates. Every so often the RC link is lost: the flight
controller sends FBWAG_NOTICE (status 1, repeated each second until
acknowledged), the companion computer (sysid 1, compid 191) answers with
status 2 echoing the notice's timestamp and flies the aircraft with
RC_CHANNELS_OVERRIDE at 20 Hz; when RC returns, status 0 is sent and echoed.
Sometimes the companion misses a notice, and sometimes never answers, in which
case the flight controller falls back to RTL. A GCS heartbeat (255/190) is
included, as in a ground-station tlog.

Every frame is built and framed by pymavlink 2.4.50 with its own bindings for
message_definitions/fbwag.xml (conformance/pymavlink/fbwag_dialect.py), one
pymavlink MAVLink object (so one sequence counter) per (sysid, compid).

Two mixes (--mix). "arduplane" (the default) streams at the rates of the
SRx_* stream groups a ground station typically requests from ArduPlane (its
firmware defaults are 1 Hz for every group and 10 Hz for PARAMS, see
libraries/GCS_MAVLink/GCS_MAVLink_Parameters.cpp; Mission Planner-style GCSs
raise them with REQUEST_DATA_STREAM), each message in the group ArduPilot
puts it in:
  HEARTBEAT 1 (FC, CC, GCS);
  EXT_STAT 2: SYS_STATUS, POWER_STATUS, MEMINFO, MISSION_CURRENT, GPS_RAW_INT,
    NAV_CONTROLLER_OUTPUT;
  RAW_SENS 2: RAW_IMU, SCALED_IMU2, SCALED_PRESSURE, SCALED_PRESSURE2;
  RC_CHAN 2: SERVO_OUTPUT_RAW, RC_CHANNELS;
  POSITION 4: GLOBAL_POSITION_INT;
  EXTRA1 10: ATTITUDE, AHRS2, AOA_SSA, ESC_TELEMETRY_1_TO_4;
  EXTRA2 4: VFR_HUD;
  EXTRA3 2: AHRS, SYSTEM_TIME, WIND, TERRAIN_REPORT, EKF_STATUS_REPORT,
    VIBRATION, BATTERY_STATUS;
  HOME_POSITION 0.1.
  At connection the GCS downloads all 1,180 parameters: PARAM_VALUE at 200/s
  (what a 115200-baud radio has left beside the streams), index 0..1179, names
  of 6 to 16 characters (157 fill all 16 bytes, without a terminating NUL;
  PARAM_VALUE's last wire field, param_type, is never 0, so its frames are
  never truncated). Extension fields are set where ArduPlane sets them: RAW_IMU id and
  temperature, SCALED_IMU2 temperature, SCALED_PRESSURE(2) the differential
  sensor's temperature, SERVO_OUTPUT_RAW servo9/servo10 (flaps, spoilers),
  GPS_RAW_INT accuracies, MEMINFO freemem32, BATTERY_STATUS time_remaining and
  charge_state, MISSION_CURRENT total and state, HOME_POSITION time_usec,
  chunked STATUSTEXT id/seq, AUTOPILOT_VERSION uid2; trailing zeros are
  truncated, so payload lengths vary by type and by frame.

"legacy" (the capture of the benchmarks before the mix above; rates in Hz, in
the order sent within a tick):
  HEARTBEAT 1; SYS_STATUS, POWER_STATUS, MEMINFO, MISSION_CURRENT 2;
  GPS_RAW_INT, NAV_CONTROLLER_OUTPUT 5; RAW_IMU, SCALED_IMU2, SCALED_PRESSURE,
  SCALED_PRESSURE2 5; RC_CHANNELS, SERVO_OUTPUT_RAW 5; GLOBAL_POSITION_INT 10;
  ATTITUDE 20; AHRS2, AOA_SSA 5; VFR_HUD 10; AHRS, SYSTEM_TIME, WIND,
  TERRAIN_REPORT, EKF_STATUS_REPORT, VIBRATION, BATTERY_STATUS,
  ESC_TELEMETRY_1_TO_4 2; HOME_POSITION 0.1.
  At connection: AUTOPILOT_VERSION, GPS_GLOBAL_ORIGIN, the banner
  STATUSTEXTs and a burst of 87 PARAM_VALUE. Events (both mixes): STATUSTEXT (one longer than
  50 characters, so sent in chunks), FBWAG_NOTICE. CC: HEARTBEAT 1 Hz,
  RC_CHANNELS_OVERRIDE 20 Hz while in control. GCS: HEARTBEAT 1 Hz.

Determinism: the same arguments give the same bytes (no wall clock, only
seeded random.Random.random(), fixed iteration orders). The flight depends
only on --seed; --v1-fraction draws from a separate generator, so framing
options never change the flight.
"""
import argparse
import math
import os
import random
import struct
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "..", "conformance", "pymavlink"))
import fbwag_dialect  # noqa: E402

G = 9.80665
DEG = math.pi / 180.0
# Home: Poltava, Ukraine; the circuit is centred on it.
HOME_LAT, HOME_LON, HOME_ALT = 49.6269, 34.4870, 157.3
M_PER_DEG_LAT = 111_132.0
M_PER_DEG_LON = 111_320.0 * math.cos(HOME_LAT * DEG)
GEOID_SEP = 22.4                     # m, ellipsoid - AMSL around Poltava
BOOT_MS = 431_220                    # FC uptime when the capture starts
UNIX_START_US = 1_748_768_400 * 1_000_000   # 2025-06-01T09:00:00Z
# MAVLink signing timestamps count 10 us units since 2015-01-01T00:00:00Z.
SIGN_EPOCH_US = 1_420_070_400 * 1_000_000
LINK_US_PER_BYTE = 87                # 115200 baud telemetry radio
TICK_MS = 10

FC, CC, GCS = (1, 1), (1, 191), (255, 190)

# ArduPlane custom modes
MANUAL, CIRCLE, FBWA, RTL = 0, 1, 5, 11


def parse_size(text):
    t = text.strip().upper().replace("IB", "").rstrip("B")
    mult = 1
    if t and t[-1] in "KMG":
        mult = 1024 ** ("KMG".index(t[-1]) + 1)
        t = t[:-1]
    try:
        n = int(float(t) * mult)
    except ValueError:
        raise argparse.ArgumentTypeError("not a size: %r (use e.g. 4194304, 512K, 4M)" % text)
    if n < 1:
        raise argparse.ArgumentTypeError("size must be positive")
    return n


def parse_seed(text):
    try:
        s = int(text, 0)
    except ValueError:
        raise argparse.ArgumentTypeError("not an integer: %r" % text)
    if s < 0:
        # random.Random(-s) == random.Random(s): refuse rather than alias
        raise argparse.ArgumentTypeError("seed must be >= 0")
    return s


def parse_fraction(text):
    try:
        f = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError("not a number: %r" % text)
    if not 0.0 <= f <= 1.0:
        raise argparse.ArgumentTypeError("must be in 0..1")
    return f


def parse_key(text):
    try:
        key = bytes.fromhex(text)
    except ValueError:
        raise argparse.ArgumentTypeError("not hex: %r" % text)
    if len(key) != 32:
        raise argparse.ArgumentTypeError("need 64 hex digits (32 bytes), got %d bytes" % len(key))
    return key


def wrap_pi(a):
    return (a + math.pi) % (2.0 * math.pi) - math.pi


def clamp(x, lo, hi):
    return lo if x < lo else hi if x > hi else x


class Rand(object):
    """Only Random.random() is used: its sequence is stable across Pythons."""

    def __init__(self, seed):
        self.r = random.Random(seed)

    def uniform(self, a, b):
        return a + (b - a) * self.r.random()

    def normal(self):
        r = self.r.random
        return (r() + r() + r() + r() - 2.0) * 1.7320508075688772

    def chance(self, p):
        return self.r.random() < p


class Noise(object):
    """Zero-mean coloured noise: first-order Gauss-Markov (std about `sigma`,
    correlation time `tau` s), optionally low-passed again (`smooth` s) so
    that its derivative stays small too."""

    def __init__(self, rnd, sigma, tau, smooth=0.0):
        self.rnd, self.g, self.x = rnd, 0.0, 0.0
        self.a = math.exp(-TICK_MS / 1000.0 / tau)
        self.b = sigma * math.sqrt(1.0 - self.a * self.a)
        self.k = 1.0 - math.exp(-TICK_MS / 1000.0 / smooth) if smooth else 1.0

    def step(self):
        self.g = self.a * self.g + self.b * self.rnd.normal()
        self.x += (self.g - self.x) * self.k
        return self.x


class Stadium(object):
    """Closed path: points at distance r from a segment of length l, rotated
    by `rot` (rad, ENU) around centre (cx, cy) metres east/north of home.
    Flown counter-clockwise (left-hand turns). l = 0 is a loiter circle."""

    def __init__(self, cx, cy, rot, l, r):
        self.cx, self.cy, self.l, self.r = cx, cy, l, r
        self.c, self.s = math.cos(rot), math.sin(rot)

    def guide(self, x, y, vg):
        """(desired course, feed-forward turn rate, cross-track error)."""
        dx, dy = x - self.cx, y - self.cy
        u = dx * self.c + dy * self.s
        v = -dx * self.s + dy * self.c
        h = self.l / 2.0
        cu = clamp(u, -h, h)
        nu, nv = u - cu, v
        dist = math.hypot(nu, nv) or 1e-6
        nu, nv = nu / dist, nv / dist
        tu, tv = -nv, nu                       # CCW tangent
        e = dist - self.r                      # > 0 outside
        course = math.atan2(tu * self.s + tv * self.c, tu * self.c - tv * self.s)
        course += math.atan(e / 60.0)
        ff = vg / self.r if abs(u) > h else 0.0
        return course, ff, e


class Plane(object):
    """Point-mass fixed-wing kinematics with a bank-to-turn guidance loop."""

    def __init__(self, rnd):
        self.rnd = rnd
        # on the circuit's southern leg, flying east-north-east (see Flight)
        self.x, self.y = 180.0 * math.sin(25 * DEG), -180.0 * math.cos(25 * DEG)
        self.course = 25 * DEG                  # ENU rad, ground track
        self.alt = 118.0                        # m above home
        self.climb = 0.0
        self.va = 18.0                          # airspeed m/s
        self.phi = 0.0                          # roll, rad (right wing down +)
        self.theta = 0.0                        # pitch, rad
        self.psi = 0.0                          # heading NED, rad
        self.p = self.q = self.r = 0.0
        self.roll_rate = 0.0
        self.throttle = 45.0
        self.wind_e, self.wind_n = -4.3, -2.5   # wind from ~240 deg, 5 m/s
        self.gust_e = Noise(rnd, 0.8, 4.0, 1.0)
        self.gust_n = Noise(rnd, 0.8, 4.0, 1.0)
        self.turb_p = Noise(rnd, 1.5 * DEG, 0.4, 0.1)
        self.turb_q = Noise(rnd, 0.8 * DEG, 0.5, 0.1)
        self.turb_va = Noise(rnd, 0.5, 2.0, 0.5)
        self.vg = 18.0
        self.vn = self.ve = 0.0
        self.phi_cmd = 0.0
        self.pitch_cmd = 0.0
        self.xtrack = 0.0
        self.dist_flown = 0.0
        self.va_target = 18.0
        self.alt_target = 120.0
        self.path = None

    def step(self, dt):
        we = self.wind_e + self.gust_e.step()
        wn = self.wind_n + self.gust_n.step()
        self.va += (self.va_target - self.va) * dt / 3.0
        va = self.va + self.turb_va.step()
        ce, cn = math.cos(self.course), math.sin(self.course)
        w_along = we * ce + wn * cn
        w_cross = -we * cn + wn * ce
        vg = w_along + math.sqrt(max(va * va - w_cross * w_cross, 1.0))
        self.vg = vg
        # guidance
        chi_d, ff, self.xtrack = self.path.guide(self.x, self.y, vg)
        omega = ff + 0.6 * wrap_pi(chi_d - self.course)
        wmax = G * math.tan(32 * DEG) / vg
        omega = clamp(omega, -wmax, wmax)
        self.phi_cmd = -math.atan(omega * vg / G)
        old_phi, old_theta, old_psi = self.phi, self.theta, self.psi
        # roll: rate limit 30 deg/s, roll acceleration limit 150 deg/s/s
        p_cmd = clamp((self.phi_cmd - self.phi) / 0.6, -30 * DEG, 30 * DEG)
        self.roll_rate += clamp(p_cmd - self.roll_rate, -150 * DEG * dt, 150 * DEG * dt)
        self.phi += self.roll_rate * dt
        self.phi += self.turb_p.step() * dt * 4.0
        self.course = wrap_pi(self.course - G * math.tan(self.phi) / vg * dt)
        # altitude and speed
        climb_cmd = clamp(0.35 * (self.alt_target - self.alt), -3.0, 4.0)
        self.climb += (climb_cmd - self.climb) * dt / 1.5
        self.alt += self.climb * dt
        gamma = math.asin(clamp(self.climb / va, -0.5, 0.5))
        alpha = (2.5 * DEG) / max(math.cos(self.phi), 0.3)
        self.pitch_cmd = gamma + alpha
        self.theta += (self.pitch_cmd - self.theta) * dt / 0.5 + self.turb_q.step() * dt * 3.0
        self.throttle = clamp(42.0 + 9.0 * self.climb + 4.0 * (self.va_target - 18.0)
                              + 6.0 * (1.0 / max(math.cos(self.phi), 0.3) - 1.0) * 10.0, 0.0, 100.0)
        self.ve = vg * math.cos(self.course)
        self.vn = vg * math.sin(self.course)
        self.x += self.ve * dt
        self.y += self.vn * dt
        self.dist_flown += vg * dt
        # heading: air velocity direction
        ae, an = self.ve - we, self.vn - wn
        self.psi = math.atan2(ae, an)
        # body rates from Euler-angle rates
        phid = (self.phi - old_phi) / dt
        thd = (self.theta - old_theta) / dt
        psd = wrap_pi(self.psi - old_psi) / dt
        cph, sph = math.cos(self.phi), math.sin(self.phi)
        cth, sth = math.cos(self.theta), math.sin(self.theta)
        self.p = phid - psd * sth
        self.q = thd * cph + psd * sph * cth
        self.r = -thd * sph + psd * cph * cth

    # derived quantities
    def lat_lon(self):
        return (HOME_LAT + self.y / M_PER_DEG_LAT, HOME_LON + self.x / M_PER_DEG_LON)

    def heading_deg(self):
        return math.degrees(self.psi) % 360.0

    def course_deg(self):
        return (90.0 - math.degrees(self.course)) % 360.0


def terrain_height(x, y):
    return 151.0 + 6.5 * math.sin(x / 900.0 + 0.4) + 4.0 * math.cos(y / 700.0) + 1.5 * math.sin((x + y) / 230.0)


def pressure_hpa(alt_amsl):
    return 1013.25 * (1.0 - 2.25577e-5 * alt_amsl) ** 5.25588


PARAMS = [  # (name, value, MAV_PARAM_TYPE)
    ("FORMAT_VERSION", 13, 4), ("SYSID_THISMAV", 1, 2), ("SYSID_MYGCS", 255, 4),
    ("SERIAL1_PROTOCOL", 2, 2), ("SERIAL1_BAUD", 115, 6), ("SERIAL2_PROTOCOL", 2, 2),
    ("SERIAL2_BAUD", 921, 6), ("SR1_RAW_SENS", 5, 4), ("SR1_EXT_STAT", 2, 4),
    ("SR1_RC_CHAN", 5, 4), ("SR1_POSITION", 10, 4), ("SR1_EXTRA1", 20, 4),
    ("SR1_EXTRA2", 10, 4), ("SR1_EXTRA3", 2, 4), ("SR1_PARAMS", 10, 4),
    ("RC_OVERRIDE_TIME", 3.0, 9), ("RC_OPTIONS", 32, 6), ("RC_PROTOCOLS", 1, 6),
    ("THR_FAILSAFE", 1, 2), ("THR_FS_VALUE", 950, 4), ("FS_SHORT_ACTN", 0, 2),
    ("FS_SHORT_TIMEOUT", 1.5, 9), ("FS_LONG_ACTN", 1, 2), ("FS_LONG_TIMEOUT", 5.0, 9),
    ("FS_GCS_ENABL", 0, 2), ("FBWAG_ENABLE", 1, 2), ("FBWAG_ACK_TMO", 1.0, 9),
    ("FBWAG_RETRIES", 3, 2), ("ARSPD_FBW_MIN", 14, 6), ("ARSPD_FBW_MAX", 26, 6),
    ("AIRSPEED_CRUISE", 18.0, 9), ("TRIM_THROTTLE", 42, 2), ("THR_MAX", 100, 2),
    ("THR_MIN", 0, 2), ("ROLL_LIMIT_DEG", 45.0, 9), ("PTCH_LIM_MAX_DEG", 20.0, 9),
    ("PTCH_LIM_MIN_DEG", -25.0, 9), ("RTL_ALTITUDE", 150.0, 9), ("RTL_RADIUS", 0, 4),
    ("WP_LOITER_RAD", 120, 4), ("WP_RADIUS", 90, 4), ("NAVL1_PERIOD", 17.0, 9),
    ("NAVL1_DAMPING", 0.75, 9), ("TECS_CLMB_MAX", 5.0, 9), ("TECS_SINK_MIN", 2.0, 9),
    ("TECS_TIME_CONST", 5.0, 9), ("TECS_LAND_SPDWGT", -1.0, 9), ("TECS_SPDWEIGHT", 1.0, 9),
    ("RLL2SRV_TCONST", 0.5, 9), ("RLL_RATE_P", 0.08, 9), ("RLL_RATE_I", 0.15, 9),
    ("RLL_RATE_D", 0.004, 9), ("PTCH_RATE_P", 0.1, 9), ("PTCH_RATE_I", 0.2, 9),
    ("PTCH_RATE_D", 0.003, 9), ("SERVO1_FUNCTION", 4, 4), ("SERVO2_FUNCTION", 19, 4),
    ("SERVO3_FUNCTION", 70, 4), ("SERVO4_FUNCTION", 21, 4), ("SERVO1_REVERSED", 0, 2),
    ("SERVO2_REVERSED", 1, 2), ("BATT_MONITOR", 4, 2), ("BATT_CAPACITY", 10000, 6),
    ("BATT_LOW_VOLT", 20.4, 9), ("BATT_CRT_VOLT", 19.8, 9), ("BATT_ARM_VOLT", 22.8, 9),
    ("COMPASS_DEC", 0.1396, 9), ("INS_GYRO_FILTER", 20, 4), ("INS_ACCEL_FILTER", 20, 4),
    ("AHRS_EKF_TYPE", 3, 2), ("EK3_ENABLE", 1, 2), ("GPS_TYPE", 2, 2),
    ("GPS_GNSS_MODE", 67, 2), ("TERRAIN_ENABLE", 1, 2), ("TERRAIN_SPACING", 100, 4),
    ("LOG_BITMASK", 65535, 6), ("FLTMODE_CH", 8, 2), ("FLTMODE1", 11, 2),
    ("FLTMODE2", 11, 2), ("FLTMODE3", 10, 2), ("FLTMODE4", 5, 2), ("FLTMODE5", 5, 2),
    ("FLTMODE6", 0, 2), ("SCHED_LOOP_RATE", 300, 4), ("ALT_HOLD_RTL", 15000, 6),
]
PARAM_COUNT = 1187
ARDUPLANE_PARAM_COUNT = 1180

# Parameter groups for the 1,180-entry download: (prefix, instances, suffixes).
# Names as ArduPlane spells them; values come from a seeded generator.
PARAM_GROUPS = [
    ("SERVO%d_", range(1, 17), ["MIN", "MAX", "TRIM", "REVERSED", "FUNCTION"]),
    ("RC%d_", range(1, 17), ["MIN", "MAX", "TRIM", "REVERSED", "DZ", "OPTION"]),
    ("SR%d_", range(0, 7), ["RAW_SENS", "EXT_STAT", "RC_CHAN", "RAW_CTRL", "POSITION",
                           "EXTRA1", "EXTRA2", "EXTRA3", "PARAMS", "ADSB"]),
    ("SERIAL%d_", range(0, 8), ["PROTOCOL", "BAUD", "OPTIONS"]),
    ("BATT%s_", ["", "2", "3", "4", "5", "6"], ["MONITOR", "CAPACITY", "VOLT_PIN", "CURR_PIN", "VOLT_MULT",
                                 "AMP_PERVLT", "AMP_OFFSET", "LOW_VOLT", "CRT_VOLT", "LOW_MAH",
                                 "CRT_MAH", "FS_LOW_ACT", "FS_CRT_ACT", "ARM_VOLT", "OPTIONS"]),
    ("INS_", [""], ["GYROFFS_X", "GYROFFS_Y", "GYROFFS_Z", "GYR2OFFS_X", "GYR2OFFS_Y",
                    "GYR2OFFS_Z", "ACCSCAL_X", "ACCSCAL_Y", "ACCSCAL_Z", "ACCOFFS_X", "ACCOFFS_Y",
                    "ACCOFFS_Z", "ACC2SCAL_X", "ACC2SCAL_Y", "ACC2SCAL_Z", "ACC2OFFS_X",
                    "ACC2OFFS_Y", "ACC2OFFS_Z", "GYRO_FILTER", "ACCEL_FILTER", "USE", "USE2",
                    "STILL_THRESH", "GYRO_RATE", "FAST_SAMPLE", "HNTCH_ENABLE", "HNTCH_FREQ",
                    "HNTCH_BW", "HNTCH_ATT", "HNTCH_REF", "HNTCH_MODE", "HNTCH_OPTS", "LOG_BAT_MASK",
                    "TCAL1_ENABLE", "TCAL2_ENABLE", "ENABLE_MASK"]),
    ("EK3_", [""], ["ENABLE", "GPS_CHECK", "IMU_MASK", "GYRO_P_NSE", "ACC_P_NSE", "GBIAS_P_NSE",
                    "ABIAS_P_NSE", "WIND_P_NSE", "WIND_PSCALE", "VELNE_M_NSE", "VELD_M_NSE",
                    "VEL_I_GATE", "POSNE_M_NSE", "POS_I_GATE", "GLITCH_RAD", "ALT_M_NSE",
                    "HGT_I_GATE", "HGT_DELAY", "MAG_M_NSE", "MAG_CAL", "MAG_I_GATE", "EAS_M_NSE",
                    "EAS_I_GATE", "RNG_M_NSE", "RNG_I_GATE", "MAX_FLOW", "FLOW_M_NSE",
                    "FLOW_I_GATE", "FLOW_DELAY", "TAU_OUTPUT", "MAGE_P_NSE", "MAGB_P_NSE",
                    "RNG_USE_HGT", "TERR_GRAD", "BCN_M_NSE", "BCN_I_GTE", "BCN_DELAY",
                    "RNG_USE_SPD", "ACC_BIAS_LIM", "MAG_MASK", "OGN_HGT_MASK", "VIS_VERR_MIN",
                    "VIS_VERR_MAX", "WENC_VERR", "FLOW_USE", "HRT_FILT", "MAG_EF_LIM",
                    "GSF_RUN_MASK", "GSF_USE_MASK", "GSF_RST_MAX", "ERR_THRESH", "AFFINITY",
                    "DRAG_BCOEF_X", "DRAG_BCOEF_Y", "DRAG_M_NSE", "DRAG_MCOEF", "OGNM_TEST_SF",
                    "GND_EFF_DZ", "PRIMARY", "LOG_LEVEL", "GPS_VACC_MAX"]),
    ("EK3_SRC%d_", range(1, 4), ["POSXY", "VELXY", "POSZ", "VELZ", "YAW"]),
    ("COMPASS_", [""], ["OFS_X", "OFS_Y", "OFS_Z", "DEC", "LEARN", "USE", "AUTODEC", "MOTCT",
                        "MOT_X", "MOT_Y", "MOT_Z", "ORIENT", "EXTERNAL", "OFS2_X", "OFS2_Y",
                        "OFS2_Z", "MOT2_X", "MOT2_Y", "MOT2_Z", "USE2", "ORIENT2", "EXTERN2",
                        "OFS3_X", "OFS3_Y", "OFS3_Z", "USE3", "ORIENT3", "EXTERN3", "DIA_X",
                        "DIA_Y", "DIA_Z", "ODI_X", "ODI_Y", "ODI_Z", "DEV_ID", "DEV_ID2", "DEV_ID3",
                        "CAL_FIT", "OFFS_MAX", "TYPEMASK", "FLTR_RNG", "AUTO_ROT", "PRIO1_ID",
                        "PRIO2_ID", "PRIO3_ID", "ENABLE", "SCALE", "SCALE2", "SCALE3", "OPTIONS"]),
    ("GPS%s_", ["", "1", "2"], ["TYPE", "NAVFILTER", "AUTO_SWITCH", "MIN_DGPS", "SBAS_MODE",
                                "MIN_ELEV", "INJECT_TO", "SBP_LOGMASK", "RAW_DATA", "GNSS_MODE",
                                "SAVE_CFG", "AUTO_CONFIG", "RATE_MS", "POS_X", "POS_Y", "POS_Z",
                                "DELAY_MS", "BLEND_MASK", "DRV_OPTIONS", "COM_PORT", "PRIMARY",
                                "CAN_NODEID", "MB_TYPE"]),
    ("ARSPD%s_", ["", "2"], ["TYPE", "USE", "OFFSET", "RATIO", "PIN", "AUTOCAL", "TUBE_ORDER",
                             "SKIP_CAL", "PSI_RANGE", "BUS", "PRIMARY", "OPTIONS", "WIND_MAX",
                             "WIND_WARN", "DEVID", "TUBE_ORDR"]),
    ("TECS_", [""], ["CLMB_MAX", "SINK_MIN", "TIME_CONST", "THR_DAMP", "INTEG_GAIN", "VERT_ACC",
                     "HGT_OMEGA", "SPD_OMEGA", "RLL2THR", "SPDWEIGHT", "PTCH_DAMP", "SINK_MAX",
                     "LAND_ARSPD", "LAND_THR", "LAND_SPDWGT", "PITCH_MAX", "PITCH_MIN",
                     "LAND_SINK", "LAND_TCONST", "LAND_DAMP", "LAND_PMAX", "APPR_SMAX",
                     "LAND_SRC", "LAND_TDAMP", "LAND_IGAIN", "LAND_PDAMP", "SYNAIRSPEED",
                     "OPTIONS", "PTCH_FF_V0", "PTCH_FF_K", "FLARE_HGT", "HDEM_TCONST"]),
    ("%s_RATE_", ["RLL", "PTCH", "YAW"], ["P", "I", "D", "FF", "IMAX", "FLTT", "FLTE", "FLTD",
                                          "SMAX", "PDMX", "D_FF", "NTF", "NTE"]),
    ("LOG_", [""], ["BACKEND_TYPE", "FILE_BUFSIZE", "DISARMED", "REPLAY", "FILE_DSRMROT",
                    "MAV_BUFSIZE", "FILE_TIMEOUT", "FILE_MB_FREE", "FILE_RATEMAX", "MAV_RATEMAX",
                    "BLK_RATEMAX", "DARM_RATEMAX", "MAX_FILES"]),
    ("FENCE_", [""], ["ENABLE", "TYPE", "ACTION", "ALT_MAX", "RADIUS", "MARGIN", "TOTAL",
                      "ALT_MIN", "RET_RALLY", "RET_ALTITUDE", "AUTOENABLE", "OPTIONS"]),
    ("RALLY_", [""], ["TOTAL", "LIMIT_KM", "INCL_HOME"]),
    ("TERRAIN_", [""], ["ENABLE", "SPACING", "OPTIONS", "MARGIN", "OFS_MAX", "CACHE_SZ"]),
    ("SCHED_", [""], ["DEBUG", "LOOP_RATE", "OPTIONS"]),
    ("BRD_", [""], ["SER1_RTSCTS", "SER2_RTSCTS", "SAFETY_DEFLT", "SBUS_OUT", "SERIAL_NUM",
                    "SAFETY_MASK", "HEAT_TARG", "TYPE", "IO_ENABLE", "SAFETYOPTION", "VBUS_MIN",
                    "VSERVO_MIN", "SD_SLOWDOWN", "PWM_VOLT_SEL", "OPTIONS", "BOOT_DELAY",
                    "HEAT_P", "HEAT_I", "HEAT_IMAX", "ALT_CONFIG", "HEAT_LOWMGN", "SD_MISSION",
                    "SD_FENCE", "IO_DSHOT"]),
    ("NTF_", [""], ["LED_BRIGHT", "BUZZ_TYPES", "LED_OVERRIDE", "DISPLAY_TYPE", "OREO_THEME",
                    "BUZZ_PIN", "LED_TYPES", "BUZZ_ON_LVL", "BUZZ_VOLUME", "LED_LEN"]),
    ("Q_", [""], ["ENABLE", "ANGLE_MAX", "TRANSITION_MS", "TRANS_DECEL", "ASSIST_SPEED",
                  "ASSIST_ALT", "ASSIST_ANGLE", "ASSIST_DELAY", "RTL_ALT", "RTL_MODE",
                  "GUIDED_MODE", "ESC_CAL", "VFWD_GAIN", "WVANE_GAIN", "WVANE_MINROLL",
                  "RTL_ALT_MIN", "LAND_SPEED", "LAND_FINAL_ALT", "TAILSIT_ENABLE", "FRAME_CLASS",
                  "FRAME_TYPE", "OPTIONS", "TRAN_PIT_MAX", "BACKTRANS_MS", "TRIM_PITCH"]),
    ("TKOFF_", [""], ["THR_MINSPD", "THR_MINACC", "THR_DELAY", "TDRAG_ELEV", "TDRAG_SPD1",
                      "ROTATE_SPD", "THR_SLEW", "PLIM_SEC", "FLAP_PCNT", "ACCEL_CNT", "ALT",
                      "DIST", "LVL_ALT", "LVL_PITCH", "GND_PITCH", "TIMEOUT", "THR_MAX",
                      "OPTIONS"]),
    ("LAND_", [""], ["SLOPE_RCALC", "ABORT_DEG", "PITCH_DEG", "FLARE_SEC", "PF_ALT",
                     "PF_SEC", "PF_ARSPD", "THR_SLEW", "DISARMDELAY", "THEN_NEUTRL",
                     "ABORT_THR", "FLAP_PERCNT", "FLARE_ALT", "TYPE", "OPTIONS", "WIND_COMP"]),
    ("SOAR_", [""], ["ENABLE", "VSPEED", "Q1", "Q2", "R", "DIST_AHEAD", "MIN_THML_S",
                     "MIN_CRSE_S", "POLAR_CD0", "POLAR_B", "POLAR_K", "ALT_MAX", "ALT_MIN",
                     "ALT_CUTOFF", "MAX_DRIFT", "MAX_RADIUS", "THML_BANK", "THML_ARSPD",
                     "CRSE_ARSPD", "THML_FLAP"]),
    ("MIS_", [""], ["TOTAL", "RESTART", "OPTIONS"]),
    ("STAT_", [""], ["BOOTCNT", "FLTTIME", "RUNTIME", "RESET"]),
    ("SIM_", [""], ["WIND_SPD", "WIND_DIR", "WIND_TURB", "WIND_T", "WIND_T_ALT", "WIND_T_COEF",
                    "WIND_DIR_Z", "GPS_DISABLE", "GPS_LAG_MS", "GPS_TYPE", "GPS_BYTELOSS",
                    "GPS_NUMSATS", "GPS_GLITCH_X", "GPS_GLITCH_Y", "GPS_GLITCH_Z", "GPS_HZ",
                    "GPS_DRIFTALT", "GPS_POS1_X", "GPS_POS1_Y", "GPS_POS1_Z", "GPS_NOISE",
                    "GPS_LOCKTIME", "GPS_ALT_OFS", "GPS_HDG", "GPS_ACC", "GPS_VERR_X",
                    "GPS_VERR_Y", "GPS_VERR_Z", "BARO_RND", "BARO_DRIFT", "BARO_GLITCH",
                    "BARO_FREEZE", "BARO_DELAY", "MAG_RND", "MAG_ERROR", "MAG_DELAY",
                    "ARSPD_RND", "ARSPD_OFS", "ARSPD_FAIL", "ARSPD_RATIO", "ACC_RND",
                    "GYR_RND", "DRIFT_SPEED", "DRIFT_TIME", "ENGINE_MUL", "ENGINE_FAIL",
                    "RC_FAIL", "RC_CHANCOUNT", "FLOAT_EXCEPT", "SPEEDUP", "IMU_COUNT",
                    "IMU_ORIENT", "IMUT_START", "IMUT_END", "IMUT_FIXED", "TEMP_START",
                    "TEMP_BRD_OFF", "TEMP_TCONST", "TERRAIN", "LOOP_DELAY", "SERVO_SPEED",
                    "SAFETY_STATE", "SONAR_SCALE", "SONAR_GLITCH", "SONAR_RND", "SONAR_POS_X",
                    "FLOW_ENABLE", "FLOW_RATE", "FLOW_DELAY", "ADSB_COUNT", "ADSB_RADIUS",
                    "ADSB_ALT", "PIN_MASK", "OPOS_LAT", "OPOS_LNG", "OPOS_ALT", "OPOS_HDG",
                    "MAG1_DEVID", "MAG2_DEVID", "MAG3_DEVID", "BATT_VOLTAGE", "BATT_CAP_AH"]),
    ("CAN_", [""], ["LOGLEVEL", "P1_DRIVER", "P1_BITRATE", "P2_DRIVER", "P2_BITRATE",
                    "D1_PROTOCOL", "D2_PROTOCOL", "D1_UC_NODE", "D1_UC_SRV_BM", "D1_UC_ESC_BM",
                    "D1_UC_OPTION", "SLCAN_CPORT", "SLCAN_SERNUM", "SLCAN_TIMOUT"]),
    ("FLTMODE%s", ["1", "2", "3", "4", "5", "6", "_CH"], [""]),
    ("RCMAP_", [""], ["ROLL", "PITCH", "THROTTLE", "YAW"]),
    ("RNGFND%d_", range(1, 5), ["TYPE", "PIN", "SCALING", "OFFSET", "FUNCTION", "MIN_CM",
                                "MAX_CM", "STOP_PIN", "RMETRIC", "PWRRNG", "GNDCLEAR", "ADDR",
                                "POS_X", "POS_Y", "POS_Z", "ORIENT"]),
    ("MNT1_", [""], ["TYPE", "DEFLT_MODE", "RC_RATE", "ROLL_MIN", "ROLL_MAX", "PITCH_MIN",
                     "PITCH_MAX", "YAW_MIN", "YAW_MAX", "RETRACT_X", "RETRACT_Y", "RETRACT_Z",
                     "NEUTRAL_X", "NEUTRAL_Y", "NEUTRAL_Z", "LEAD_RLL", "LEAD_PTCH", "SYSID_DFLT",
                     "DEVID", "OPTIONS"]),
    ("AHRS_", [""], ["GPS_GAIN", "GPS_USE", "YAW_P", "RP_P", "WIND_MAX", "TRIM_X", "TRIM_Y",
                     "TRIM_Z", "ORIENTATION", "COMP_BETA", "GPS_MINSATS", "EKF_TYPE",
                     "CUSTOM_ROLL", "CUSTOM_PIT", "CUSTOM_YAW", "OPTIONS"]),
    ("ARMING_", [""], ["REQUIRE", "ACCTHRESH", "RUDDER", "MIS_ITEMS", "CHECK", "OPTIONS",
                       "MAGTHRESH", "CRSDP_IGN"]),
    ("OSD%d_", range(1, 7), ["ENABLE", "TXT_RES", "FONT", "V_OFFSET", "H_OFFSET", "ALTITUDE_EN",
                             "ALTITUDE_X", "ALTITUDE_Y", "BAT_VOLT_EN", "BAT_VOLT_X", "BAT_VOLT_Y",
                             "RSSI_EN", "RSSI_X", "RSSI_Y", "CURRENT_EN", "CURRENT_X",
                             "CURRENT_Y"]),
]


def arduplane_params(seed):
    """1,180 (name, value, MAV_PARAM_TYPE): the 87 above first, then the
    groups' names in order, without repeats; values from a generator of
    their own (so the flight does not depend on them)."""
    rnd = Rand(seed + 0x9A8A0000)
    out, seen = list(PARAMS), set(p[0] for p in PARAMS)
    for prefix, instances, suffixes in PARAM_GROUPS:
        for inst in instances:
            for suffix in suffixes:
                name = (prefix % inst if "%" in prefix else prefix) + suffix
                if len(name) > 16 or name in seen:
                    continue
                seen.add(name)
                kind = int(rnd.uniform(0, 4))
                if kind == 0:
                    out.append((name, round(rnd.uniform(-50, 50), 3), 9))
                else:
                    ptype = (2, 4, 6)[kind - 1]
                    hi = (100, 2000, 100000)[kind - 1]
                    out.append((name, int(rnd.uniform(0, hi)), ptype))
                if len(out) == ARDUPLANE_PARAM_COUNT:
                    return out
    raise AssertionError("PARAM_GROUPS give only %d names" % len(out))

BANNER = [
    (6, "ArduPlane V4.5.7 (2a3dc4b7)"),
    (6, "ChibiOS: 6a85082c"),
    (6, "MatekH743 0034001F 3131510D 33363935"),
    (6, "IOMCU: 0 0 0"),
    (6, "RCOut: PWM:1-12"),
    (6, "IMU0: fast sampling enabled 8.0kHz/1.0kHz"),
    (6, "FBWAG delegation v1: CC sysid 1 compid 191, ack timeout 1.0 s"),
    (6, "Frame: PLANE"),
]


class Link(object):
    """The single telemetry link all senders share: frames them with pymavlink
    and appends them to the capture (optionally as .tlog records)."""

    class _Catch(object):
        last = b""

        def write(self, b):
            self.last = b

    def __init__(self, mod, args):
        self.mod = mod
        self.args = args
        self.out = bytearray()
        self.frames = 0
        self.v1_frames = 0
        self.signed_frames = 0
        self.types = {}
        self.frame_rnd = Rand(args.seed + 0x5EED0000)
        self.busy_until_us = 0
        self.catch = Link._Catch()
        self.mavs = {}
        self.min_len = (fbwag_dialect.wire_min_lengths()
                        if args.v1_fraction > 0 and args.v1_extensions == "drop" else None)
        for ids in (FC, CC, GCS):
            mav = mod.MAVLink(self.catch, srcSystem=ids[0], srcComponent=ids[1])
            if args.sign_key is not None:
                mav.signing.secret_key = args.sign_key
                mav.signing.link_id = 0
                mav.signing.sign_outgoing = True
                mav.signing.timestamp = (UNIX_START_US - SIGN_EPOCH_US) // 10
            self.mavs[ids] = mav

    def send(self, ids, msg, t_ms):
        mav = self.mavs[ids]
        # type(msg).id, not msg.id: a field named "id" (STATUSTEXT, RAW_IMU,
        # BATTERY_STATUS...) shadows pymavlink's class attribute on instances.
        msgid = type(msg).id
        v1 = False
        if self.args.v1_fraction > 0 and msgid <= 255:
            v1 = self.frame_rnd.r.random() < self.args.v1_fraction
        start_us = max((t_ms - BOOT_MS) * 1000, self.busy_until_us)
        if mav.signing.sign_outgoing:
            # a real signer uses its clock; never go backwards
            now10 = (UNIX_START_US + start_us - SIGN_EPOCH_US) // 10
            if now10 > mav.signing.timestamp:
                mav.signing.timestamp = now10
        mav.send(msg, force_mavlink1=v1)
        buf = self.catch.last
        if v1:
            self.v1_frames += 1
            if self.min_len is not None:
                buf = self._drop_extensions(buf, msgid, msg.crc_extra)
        elif mav.signing.sign_outgoing:
            self.signed_frames += 1
        end_us = start_us + len(buf) * LINK_US_PER_BYTE
        self.busy_until_us = end_us
        if self.args.tlog:
            self.out += struct.pack(">Q", UNIX_START_US + end_us)
        self.out += buf
        self.frames += 1
        name = msg.msgname
        self.types[name] = self.types.get(name, 0) + 1

    def _drop_extensions(self, buf, msgid, crc_extra):
        """MAVLink 1 as the C library (ArduPilot) sends it: base fields only.
        pymavlink keeps extension fields in MAVLink 1 frames."""
        n = self.min_len[msgid]
        if buf[1] <= n:
            return buf
        frame = bytearray(buf[:6] + buf[6:6 + n])
        frame[1] = n
        crc = self.mod.x25crc(frame[1:])
        crc.accumulate(struct.pack("B", crc_extra))
        return bytes(frame) + struct.pack("<H", crc.crc)


class Flight(object):
    def __init__(self, mod, link, rnd, mix="legacy", seed=1):
        self.arduplane = mix == "arduplane"
        self.seed = seed
        self.m = mod
        self.link = link
        self.rnd = rnd
        self.plane = Plane(rnd)
        self.circuit = Stadium(0.0, 0.0, 25 * DEG, 700.0, 180.0)
        self.cc_loiter = Stadium(520.0, 610.0, 0.0, 0.0, 250.0)
        self.rtl_loiter = Stadium(0.0, 0.0, 0.0, 0.0, 120.0)
        self.plane.path = self.circuit
        self.mode = FBWA
        self.rc_ok = True
        self.cc_in_control = False
        self.failsafe = False
        self.events = []          # (t_ms, order, fn)
        self.event_order = 0
        self.text_id = 0
        self.notice_ts = None
        self.notice_tries = 0
        self.acked = False
        self.battery_mah = 2310.0
        self.rssi_base = 205
        self.clip = [0, 0, 0]
        self.vib = [Noise(rnd, 0.6, 1.0) for _ in range(3)]
        self.imu_noise = [Noise(rnd, 25.0, 0.05) for _ in range(6)]
        self.baro_noise = Noise(rnd, 0.03, 0.5)
        self.gps_noise = [Noise(rnd, 0.25, 3.0) for _ in range(3)]
        self.esc_temp = 38.0
        self.override = None
        self.cc_plan = "ok"
        self.last_rc = [1500, 1500, 1420, 1500, 1100, 1500, 1100, 1750] + [1500] * 4 + [1000] * 4
        m = mod
        self.base_mode_manual = (m.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | m.MAV_MODE_FLAG_STABILIZE_ENABLED
                                 | m.MAV_MODE_FLAG_MANUAL_INPUT_ENABLED | m.MAV_MODE_FLAG_SAFETY_ARMED)
        self.base_mode_auto = (m.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | m.MAV_MODE_FLAG_STABILIZE_ENABLED
                               | m.MAV_MODE_FLAG_GUIDED_ENABLED | m.MAV_MODE_FLAG_AUTO_ENABLED
                               | m.MAV_MODE_FLAG_SAFETY_ARMED)
        self.schedule_rc_loss(BOOT_MS + int(rnd.uniform(40_000, 70_000)))

    def update(self, t):
        """Per-tick targets: the pilot climbs and descends gently on the circuit."""
        if self.mode == FBWA and not self.cc_in_control and self.rc_ok:
            d = self.plane.dist_flown
            self.plane.alt_target = 120.0 + 15.0 * math.sin(d / 1900.0) + 6.0 * math.sin(d / 410.0)
            self.plane.va_target = 18.0 + 1.5 * math.sin(d / 2600.0)

    # ---- events -------------------------------------------------------
    def at(self, t_ms, fn):
        t_ms = (t_ms // TICK_MS) * TICK_MS
        self.events.append((t_ms, self.event_order, fn))
        self.event_order += 1
        self.events.sort()

    def run_events(self, t):
        while self.events and self.events[0][0] <= t:
            _, _, fn = self.events.pop(0)
            fn(t)

    def schedule_rc_loss(self, t):
        self.at(t, self.rc_lost)

    def rc_lost(self, t):
        self.rc_ok = False
        self.rssi_base = 0
        # FS_SHORT_TIMEOUT 1.5 s before the FC declares the failsafe
        self.at(t + 1500, self.declare_failsafe)
        duration = int(self.rnd.uniform(14_000, 45_000))
        self.at(t + duration, self.rc_regained)

    def declare_failsafe(self, t):
        if self.rc_ok:
            return
        self.failsafe = True
        self.acked = False
        self.notice_ts = t          # FC time since boot, ms: identifies the event
        self.notice_tries = 0
        self.text(t, 4, "RC Short Failsafe On")
        self.text(t, 4, "FBWAG: RC lost at %.5f,%.5f alt %dm, delegating control to companion computer"
                  % (self.plane.lat_lon() + (int(self.plane.alt),)))
        # the CC's behaviour for this event
        r = self.rnd.r.random()
        self.cc_plan = "none" if r < 0.12 else "late" if r < 0.35 else "ok"
        self.send_notice(t)

    def send_notice(self, t):
        if self.acked or self.rc_ok:
            return
        if self.notice_tries >= 3:
            self.mode = RTL
            self.plane.path = self.rtl_loiter
            self.plane.alt_target = 150.0
            self.text(t, 2, "FBWAG: no CC ack after 3 notices, RTL")
            return
        self.notice_tries += 1
        self.notice(FC, t, 1, self.notice_ts)
        plan = self.cc_plan
        if plan == "ok" or (plan == "late" and self.notice_tries == 2):
            self.at(t + int(self.rnd.uniform(30, 160)), self.cc_ack_takeover)
        self.at(t + 1000, self.send_notice)

    def notice(self, ids, t, status, ts):
        self.link.send(ids, self.m.MAVLink_fbwag_notice_message(
            ids[0], ids[1], status, b"FBWAG", ts), t)

    def cc_ack_takeover(self, t):
        if self.rc_ok or self.acked:
            return
        self.notice(CC, t, 2, self.notice_ts)
        self.acked = True
        self.cc_in_control = True
        self.plane.path = self.cc_loiter
        self.plane.alt_target = 100.0
        self.plane.va_target = 17.0
        self.at(t + int(self.rnd.uniform(20, 60)), lambda t2: self.text(t2, 6, "FBWAG: CC takeover confirmed"))

    def rc_regained(self, t):
        self.rc_ok = True
        self.rssi_base = 205
        was_cc = self.cc_in_control
        self.cc_in_control = False
        self.override = None
        if self.failsafe:
            self.failsafe = False
            self.text(t, 6, "RC Short Failsafe Cleared")
            ts = t
            self.notice(FC, t, 0, ts)
            if was_cc or self.cc_plan != "none":
                self.at(t + int(self.rnd.uniform(30, 160)), lambda t2: self.notice(CC, t2, 0, ts))
        self.mode = FBWA
        self.plane.path = self.circuit
        self.plane.alt_target = 120.0
        self.plane.va_target = 18.0
        self.text(t, 6, "Mode FBWA")
        self.schedule_rc_loss(t + int(self.rnd.uniform(60_000, 150_000)))

    def text(self, t, severity, s):
        data = s.encode("ascii")
        if len(data) <= 50:
            self.link.send(FC, self.m.MAVLink_statustext_message(severity, data, 0, 0), t)
            return
        self.text_id = (self.text_id % 65535) + 1
        for i in range(0, len(data), 50):
            self.link.send(FC, self.m.MAVLink_statustext_message(
                severity, data[i:i + 50], self.text_id, i // 50), t)

    # ---- one-off messages at connection --------------------------------
    def connect(self, t):
        m = self.m
        caps = (m.MAV_PROTOCOL_CAPABILITY_MISSION_FLOAT | m.MAV_PROTOCOL_CAPABILITY_PARAM_FLOAT
                | m.MAV_PROTOCOL_CAPABILITY_MISSION_INT | m.MAV_PROTOCOL_CAPABILITY_COMMAND_INT
                | m.MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_GLOBAL_INT
                | m.MAV_PROTOCOL_CAPABILITY_FTP | m.MAV_PROTOCOL_CAPABILITY_SET_ATTITUDE_TARGET
                | m.MAV_PROTOCOL_CAPABILITY_MAVLINK2 | m.MAV_PROTOCOL_CAPABILITY_MISSION_FENCE
                | m.MAV_PROTOCOL_CAPABILITY_MISSION_RALLY | m.MAV_PROTOCOL_CAPABILITY_COMPASS_CALIBRATION)
        self.link.send(FC, m.MAVLink_autopilot_version_message(
            caps, 0x040507FF, 0, 0, 0x00340000,
            [0x32, 0x61, 0x33, 0x64, 0x63, 0x34, 0x62, 0x37],   # "2a3dc4b7"
            [0] * 8,
            [0x36, 0x61, 0x38, 0x35, 0x30, 0x38, 0x32, 0x63],   # "6a85082c"
            0x1209, 0x5741, 0x0034001F3131510D,
            [0x00, 0x34, 0x00, 0x1F, 0x31, 0x31, 0x51, 0x0D, 0x33, 0x36, 0x39, 0x35]
            + [0] * 6), t)
        for sev, s in BANNER:
            self.text(t, sev, s)
        self.link.send(FC, m.MAVLink_gps_global_origin_message(
            int(HOME_LAT * 1e7), int(HOME_LON * 1e7), int(HOME_ALT * 1000),
            (UNIX_START_US - 600_000_000)), t)
        if self.arduplane:
            # the whole list, 2 per 10-ms tick (200/s), in index order
            params = arduplane_params(self.seed)
            for i, (name, value, ptype) in enumerate(params):
                self.at(t + 40 + TICK_MS * (i // 2),
                        self._param_sender(i, name, value, ptype, len(params), i))
            return
        for i, (name, value, ptype) in enumerate(PARAMS):
            self.at(t + 40 + 50 * i, self._param_sender(i, name, value, ptype, PARAM_COUNT,
                                                        17 + i * 13 % PARAM_COUNT))

    def _param_sender(self, i, name, value, ptype, count, index):
        def send(t):
            self.link.send(FC, self.m.MAVLink_param_value_message(
                name.encode("ascii"), float(value), ptype, count, index), t)
        return send

    # ---- periodic streams ----------------------------------------------
    def streams(self):
        """(name, sender, period ms, phase ms, function), sent in this order."""
        if self.arduplane:
            return self.arduplane_streams()
        return [
            ("HEARTBEAT", FC, 1000, 0, self.s_heartbeat),
            ("HEARTBEAT", CC, 1000, 370, self.s_cc_heartbeat),
            ("HEARTBEAT", GCS, 1000, 610, self.s_gcs_heartbeat),
            ("SYS_STATUS", FC, 500, 20, self.s_sys_status),
            ("POWER_STATUS", FC, 500, 20, self.s_power_status),
            ("MEMINFO", FC, 500, 20, self.s_meminfo),
            ("MISSION_CURRENT", FC, 500, 20, self.s_mission_current),
            ("GPS_RAW_INT", FC, 200, 30, self.s_gps_raw_int),
            ("NAV_CONTROLLER_OUTPUT", FC, 200, 30, self.s_nav_controller_output),
            ("RAW_IMU", FC, 200, 60, self.s_raw_imu),
            ("SCALED_IMU2", FC, 200, 60, self.s_scaled_imu2),
            ("SCALED_PRESSURE", FC, 200, 60, self.s_scaled_pressure),
            ("SCALED_PRESSURE2", FC, 200, 60, self.s_scaled_pressure2),
            ("RC_CHANNELS", FC, 200, 110, self.s_rc_channels),
            ("SERVO_OUTPUT_RAW", FC, 200, 110, self.s_servo_output_raw),
            ("GLOBAL_POSITION_INT", FC, 100, 0, self.s_global_position_int),
            ("ATTITUDE", FC, 50, 10, self.s_attitude),
            ("AHRS2", FC, 200, 130, self.s_ahrs2),
            ("AOA_SSA", FC, 200, 130, self.s_aoa_ssa),
            ("VFR_HUD", FC, 100, 40, self.s_vfr_hud),
            ("AHRS", FC, 500, 270, self.s_ahrs),
            ("SYSTEM_TIME", FC, 500, 270, self.s_system_time),
            ("WIND", FC, 500, 270, self.s_wind),
            ("TERRAIN_REPORT", FC, 500, 270, self.s_terrain_report),
            ("EKF_STATUS_REPORT", FC, 500, 270, self.s_ekf_status_report),
            ("VIBRATION", FC, 500, 270, self.s_vibration),
            ("BATTERY_STATUS", FC, 500, 270, self.s_battery_status),
            ("ESC_TELEMETRY_1_TO_4", FC, 500, 270, self.s_esc_telemetry),
            ("HOME_POSITION", FC, 10000, 4990, self.s_home_position),
            ("RC_CHANNELS_OVERRIDE", CC, 50, 30, self.s_rc_override),
        ]

    def arduplane_streams(self):
        """The SRx-like rates of the "arduplane" mix (see the module doc),
        grouped as ArduPilot's GCS_MAVLink_Parameters.cpp groups them; each
        group's phase within its period keeps the bursts apart."""
        return [
            ("HEARTBEAT", FC, 1000, 0, self.s_heartbeat),
            ("HEARTBEAT", CC, 1000, 370, self.s_cc_heartbeat),
            ("HEARTBEAT", GCS, 1000, 610, self.s_gcs_heartbeat),
            # EXT_STAT 2 Hz
            ("SYS_STATUS", FC, 500, 20, self.s_sys_status),
            ("POWER_STATUS", FC, 500, 20, self.s_power_status),
            ("MEMINFO", FC, 500, 20, self.s_meminfo),
            ("MISSION_CURRENT", FC, 500, 20, self.s_mission_current),
            ("GPS_RAW_INT", FC, 500, 20, self.s_gps_raw_int),
            ("NAV_CONTROLLER_OUTPUT", FC, 500, 20, self.s_nav_controller_output),
            # RAW_SENS 2 Hz
            ("RAW_IMU", FC, 500, 60, self.s_raw_imu),
            ("SCALED_IMU2", FC, 500, 60, self.s_scaled_imu2),
            ("SCALED_PRESSURE", FC, 500, 60, self.s_scaled_pressure),
            ("SCALED_PRESSURE2", FC, 500, 60, self.s_scaled_pressure2),
            # RC_CHAN 2 Hz
            ("SERVO_OUTPUT_RAW", FC, 500, 110, self.s_servo_output_raw),
            ("RC_CHANNELS", FC, 500, 110, self.s_rc_channels),
            # POSITION 4 Hz
            ("GLOBAL_POSITION_INT", FC, 250, 0, self.s_global_position_int),
            # EXTRA1 10 Hz
            ("ATTITUDE", FC, 100, 10, self.s_attitude),
            ("AHRS2", FC, 100, 10, self.s_ahrs2),
            ("AOA_SSA", FC, 100, 10, self.s_aoa_ssa),
            ("ESC_TELEMETRY_1_TO_4", FC, 100, 10, self.s_esc_telemetry),
            # EXTRA2 4 Hz
            ("VFR_HUD", FC, 250, 40, self.s_vfr_hud),
            # EXTRA3 2 Hz
            ("AHRS", FC, 500, 270, self.s_ahrs),
            ("WIND", FC, 500, 270, self.s_wind),
            ("SYSTEM_TIME", FC, 500, 270, self.s_system_time),
            ("TERRAIN_REPORT", FC, 500, 270, self.s_terrain_report),
            ("BATTERY_STATUS", FC, 500, 270, self.s_battery_status),
            ("EKF_STATUS_REPORT", FC, 500, 270, self.s_ekf_status_report),
            ("VIBRATION", FC, 500, 270, self.s_vibration),
            ("HOME_POSITION", FC, 10000, 4990, self.s_home_position),
            ("RC_CHANNELS_OVERRIDE", CC, 50, 30, self.s_rc_override),
        ]

    def send(self, ids, msg, t):
        self.link.send(ids, msg, t)

    def s_heartbeat(self, t):
        m = self.m
        base = self.base_mode_auto if self.mode in (RTL,) else self.base_mode_manual
        status = m.MAV_STATE_CRITICAL if self.failsafe else m.MAV_STATE_ACTIVE
        self.send(FC, m.MAVLink_heartbeat_message(
            m.MAV_TYPE_FIXED_WING, m.MAV_AUTOPILOT_ARDUPILOTMEGA, base, self.mode, status, 3), t)

    def s_cc_heartbeat(self, t):
        m = self.m
        self.send(CC, m.MAVLink_heartbeat_message(
            m.MAV_TYPE_ONBOARD_CONTROLLER, m.MAV_AUTOPILOT_INVALID, 0, 0, m.MAV_STATE_ACTIVE, 3), t)

    def s_gcs_heartbeat(self, t):
        m = self.m
        self.send(GCS, m.MAVLink_heartbeat_message(
            m.MAV_TYPE_GCS, m.MAV_AUTOPILOT_INVALID, 0, 0, 0, 3), t)

    def volts(self):
        return 24.9 - 0.00035 * self.battery_mah - 0.018 * self.current()

    def current(self):
        return 3.2 + 0.21 * self.plane.throttle

    def s_sys_status(self, t):
        m = self.m
        sensors = (m.MAV_SYS_STATUS_SENSOR_3D_GYRO | m.MAV_SYS_STATUS_SENSOR_3D_ACCEL
                   | m.MAV_SYS_STATUS_SENSOR_3D_MAG | m.MAV_SYS_STATUS_SENSOR_ABSOLUTE_PRESSURE
                   | m.MAV_SYS_STATUS_SENSOR_DIFFERENTIAL_PRESSURE | m.MAV_SYS_STATUS_SENSOR_GPS
                   | m.MAV_SYS_STATUS_SENSOR_ANGULAR_RATE_CONTROL | m.MAV_SYS_STATUS_SENSOR_ATTITUDE_STABILIZATION
                   | m.MAV_SYS_STATUS_SENSOR_YAW_POSITION | m.MAV_SYS_STATUS_SENSOR_Z_ALTITUDE_CONTROL
                   | m.MAV_SYS_STATUS_SENSOR_XY_POSITION_CONTROL | m.MAV_SYS_STATUS_SENSOR_MOTOR_OUTPUTS
                   | m.MAV_SYS_STATUS_SENSOR_RC_RECEIVER | m.MAV_SYS_STATUS_AHRS
                   | m.MAV_SYS_STATUS_TERRAIN | m.MAV_SYS_STATUS_LOGGING | m.MAV_SYS_STATUS_SENSOR_BATTERY
                   | m.MAV_SYS_STATUS_PREARM_CHECK)
        health = sensors if self.rc_ok else sensors & ~m.MAV_SYS_STATUS_SENSOR_RC_RECEIVER
        load = int(clamp(312 + 25 * math.sin(t / 7300.0) + self.rnd.uniform(-8, 8), 0, 1000))
        remaining = int(clamp(100 - self.battery_mah / 100.0, 0, 100))
        self.send(FC, m.MAVLink_sys_status_message(
            sensors, sensors, health, load, int(self.volts() * 1000), int(self.current() * 100),
            remaining, 0, 0, 0, 0, 0, 0), t)

    def s_power_status(self, t):
        self.send(FC, self.m.MAVLink_power_status_message(
            int(5118 + self.rnd.uniform(-6, 6)), int(5241 + self.rnd.uniform(-20, 20)), 3), t)

    def s_meminfo(self, t):
        self.send(FC, self.m.MAVLink_meminfo_message(0, 65535, 164312), t)

    def s_mission_current(self, t):
        self.send(FC, self.m.MAVLink_mission_current_message(0, 7, 2, 0), t)

    def s_gps_raw_int(self, t):
        p = self.plane
        lat, lon = p.lat_lon()
        n = self.gps_noise
        lat += n[0].x / M_PER_DEG_LAT
        lon += n[1].x / M_PER_DEG_LON
        alt = HOME_ALT + p.alt + n[2].x * 2
        sats = 17 + int(2.5 * math.sin(t / 97_000.0))
        self.send(FC, self.m.MAVLink_gps_raw_int_message(
            (t - 95) * 1000, 3, int(round(lat * 1e7)), int(round(lon * 1e7)), int(alt * 1000),
            int(72 + 8 * math.sin(t / 41_000.0)), 118, int(p.vg * 100), int(p.course_deg() * 100) % 36000,
            sats, int((alt + GEOID_SEP) * 1000), int(690 + 60 * math.sin(t / 33_000.0)), 1150,
            int(180 + 40 * math.sin(t / 21_000.0)), 0, 0), t)

    def s_nav_controller_output(self, t):
        p = self.plane
        brg = int(round(p.course_deg())) % 360
        brg = brg - 360 if brg > 180 else brg
        self.send(FC, self.m.MAVLink_nav_controller_output_message(
            math.degrees(p.phi_cmd), math.degrees(p.pitch_cmd), brg, brg, 0,
            p.alt_target - p.alt, (p.va_target - p.va) * 100.0, p.xtrack), t)

    def _imu(self, noise_scale):
        p = self.plane
        n = [x.x * noise_scale for x in self.imu_noise]
        cph, sph = math.cos(p.phi), math.sin(p.phi)
        cth, sth = math.cos(p.theta), math.sin(p.theta)
        acc = (1000.0 * sth + n[0], n[1] + 1000.0 * 0.01 * sph, -1000.0 / max(cph, 0.3) * cth + n[2])
        gyro = (p.p * 1000 + n[3] * 0.4, p.q * 1000 + n[4] * 0.4, p.r * 1000 + n[5] * 0.4)
        # earth field in NED, mGauss: 196 north, 27 east, 452 down
        mn, me, md = 196.0, 27.0, 452.0
        cps, sps = math.cos(p.psi), math.sin(p.psi)
        bx = cth * cps * mn + cth * sps * me - sth * md
        by = (sph * sth * cps - cph * sps) * mn + (sph * sth * sps + cph * cps) * me + sph * cth * md
        bz = (cph * sth * cps + sph * sps) * mn + (cph * sth * sps - sph * cps) * me + cph * cth * md
        return acc, gyro, (bx + 12, by - 7, bz + 30)

    def s_raw_imu(self, t):
        acc, gyro, mag = self._imu(1.0)
        self.send(FC, self.m.MAVLink_raw_imu_message(
            t * 1000 - 3100, *([int(v) for v in acc + gyro + mag] + [0, 4215])), t)

    def s_scaled_imu2(self, t):
        acc, gyro, mag = self._imu(1.3)
        self.send(FC, self.m.MAVLink_scaled_imu2_message(
            t - 3, *([int(v) for v in acc + gyro + mag] + [3980])), t)

    def s_scaled_pressure(self, t):
        p = self.plane
        press = pressure_hpa(HOME_ALT + p.alt) + self.baro_noise.x
        diff = 0.5 * 1.19 * p.va * p.va / 100.0
        # arduplane: the differential (airspeed) sensor's own temperature
        tdiff = int(3120 - 0.65 * p.alt + 40 * math.sin(t / 90_000.0)) if self.arduplane else 0
        self.send(FC, self.m.MAVLink_scaled_pressure_message(
            t - 4, press, diff, int(2870 - 0.65 * p.alt), tdiff), t)

    def s_scaled_pressure2(self, t):
        p = self.plane
        diff = 0.5 * 1.19 * p.va * p.va / 100.0 + self.baro_noise.x * 0.1
        self.send(FC, self.m.MAVLink_scaled_pressure2_message(
            t - 6, 0.0, diff, int(2410 - 0.65 * p.alt), int(2410 - 0.65 * p.alt)), t)

    def pilot_sticks(self):
        p = self.plane
        roll = int(clamp(1500 + p.phi_cmd / (45 * DEG) * 500, 1000, 2000))
        pitch = int(clamp(1500 - p.pitch_cmd / (20 * DEG) * 500, 1000, 2000))
        thr = int(1000 + p.throttle * 10)
        return roll, pitch, thr, 1500 + int(8 * math.sin(p.dist_flown / 300.0))

    def s_rc_channels(self, t):
        if self.override is not None:
            ch = list(self.override[:8]) + [1500] * 4 + [1000] * 4
        elif self.rc_ok:
            r, pi, th, ya = self.pilot_sticks()
            self.last_rc = [r, pi, th, ya, 1100, 1500, 1100, 1750] + [1500] * 4 + [1000] * 4
            ch = self.last_rc
        else:
            ch = self.last_rc           # receiver stopped sending: values hold
        rssi = 0 if not self.rc_ok else int(clamp(self.rssi_base + self.rnd.uniform(-15, 15), 0, 254))
        self.send(FC, self.m.MAVLink_rc_channels_message(
            t - 2, 16 if self.rc_ok else 0, *(ch + [0, 0, rssi])), t)

    def s_servo_output_raw(self, t):
        p = self.plane
        ail = int(1500 + clamp(p.phi_cmd - p.phi, -0.5, 0.5) * 900 + p.phi * 80)
        ele = int(1500 - (p.pitch_cmd - p.theta) * 900 - 40)
        thr = int(1000 + p.throttle * 10)
        rud = int(1500 + p.r * 60)
        self.send(FC, self.m.MAVLink_servo_output_raw_message(
            (t * 1000 - 1200) & 0xFFFFFFFF, 0, ail, ele, thr, rud, 1500, 0, 0, 1100,
            *self.servo_ext()), t)

    def servo_ext(self):
        """SERVO_OUTPUT_RAW's extension fields (servo9_raw..servo16_raw):
        arduplane: flaps on 9 (down while the companion flies), spoilers on
        10; the rest unused (0, so truncated)."""
        if not self.arduplane:
            return []
        flaps = 1650 if self.cc_in_control else 1100
        return [flaps, 1000, 0, 0, 0, 0, 0, 0]

    def s_global_position_int(self, t):
        p = self.plane
        lat, lon = p.lat_lon()
        self.send(FC, self.m.MAVLink_global_position_int_message(
            t, int(round(lat * 1e7)), int(round(lon * 1e7)), int((HOME_ALT + p.alt) * 1000),
            int(p.alt * 1000), int(p.vn * 100), int(p.ve * 100), int(-p.climb * 100),
            int(p.heading_deg() * 100) % 36000), t)

    def s_attitude(self, t):
        p = self.plane
        self.send(FC, self.m.MAVLink_attitude_message(
            t, p.phi, p.theta, wrap_pi(p.psi), p.p, p.q, p.r), t)

    def s_ahrs2(self, t):
        p = self.plane
        lat, lon = p.lat_lon()
        self.send(FC, self.m.MAVLink_ahrs2_message(
            p.phi + 0.004, p.theta - 0.006, wrap_pi(p.psi + 0.011), HOME_ALT + p.alt - 0.7,
            int(round(lat * 1e7)) + 3, int(round(lon * 1e7)) - 5), t)

    def s_aoa_ssa(self, t):
        p = self.plane
        self.send(FC, self.m.MAVLink_aoa_ssa_message(
            t * 1000, math.degrees(p.pitch_cmd - math.asin(clamp(p.climb / p.va, -0.5, 0.5))),
            math.degrees(p.r / max(p.va, 1.0)) * 0.5), t)

    def s_vfr_hud(self, t):
        p = self.plane
        self.send(FC, self.m.MAVLink_vfr_hud_message(
            p.va, p.vg, int(p.heading_deg()) % 360, int(p.throttle), HOME_ALT + p.alt, p.climb), t)

    def s_ahrs(self, t):
        self.send(FC, self.m.MAVLink_ahrs_message(
            0.00012, -0.00031, 0.00007 + 0.00002 * math.sin(t / 60_000.0), 0.0, 0.0,
            0.0021 + 0.0008 * abs(math.sin(self.plane.phi)), 0.0113), t)

    def s_system_time(self, t):
        self.send(FC, self.m.MAVLink_system_time_message(
            UNIX_START_US + (t - BOOT_MS) * 1000, t), t)

    def s_wind(self, t):
        p = self.plane
        d = math.degrees(math.atan2(-p.wind_e, -p.wind_n)) % 360.0
        self.send(FC, self.m.MAVLink_wind_message(
            d, math.hypot(p.wind_e, p.wind_n) + p.gust_e.x * 0.3, 0.1 * p.gust_n.x), t)

    def s_terrain_report(self, t):
        p = self.plane
        lat, lon = p.lat_lon()
        th = terrain_height(p.x, p.y)
        self.send(FC, self.m.MAVLink_terrain_report_message(
            int(round(lat * 1e7)), int(round(lon * 1e7)), 100, th, HOME_ALT + p.alt - th, 0, 504), t)

    def s_ekf_status_report(self, t):
        s = math.sin(t / 13_000.0)
        self.send(FC, self.m.MAVLink_ekf_status_report_message(
            0x033F, 0.021 + 0.01 * s, 0.008, 0.034 + 0.004 * s, 0.027, 0.0,
            0.0 if self.mode == RTL else 0.045), t)

    def s_vibration(self, t):
        v = [max(0.0, 3.2 + 0.6 * i + n.step() * 2.0) for i, n in enumerate(self.vib)]
        if v[2] > 5.0:
            self.clip[2] += 1
        self.send(FC, self.m.MAVLink_vibration_message(
            t * 1000, v[0], v[1], v[2], self.clip[0], self.clip[1], self.clip[2]), t)

    def s_battery_status(self, t):
        self.battery_mah += self.current() * 0.5 / 3.6
        volts = self.volts()
        remaining = int(clamp(100 - self.battery_mah / 100.0, 0, 100))
        self.send(FC, self.m.MAVLink_battery_status_message(
            0, 0, 0, 32767, [int(volts * 1000)] + [65535] * 9, int(self.current() * 100),
            int(self.battery_mah), int(self.battery_mah * 22.9 * 0.036), remaining,
            int(max(0.0, (10000 - self.battery_mah) / self.current() * 3.6)), 1, [0, 0, 0, 0], 0, 0), t)

    def s_esc_telemetry(self, t):
        p = self.plane
        # the same time constant at 2 Hz (legacy) and 10 Hz (arduplane)
        k = 0.002 if self.arduplane else 0.01
        self.esc_temp += (34.0 + 0.3 * p.throttle - self.esc_temp) * k
        rpm = int(p.throttle * 95)
        self.send(FC, self.m.MAVLink_esc_telemetry_1_to_4_message(
            [int(self.esc_temp), 0, 0, 0], [int(self.volts() * 100), 0, 0, 0],
            [int(self.current() * 100), 0, 0, 0], [int(self.battery_mah), 0, 0, 0],
            [rpm, 0, 0, 0], [(t // 500) & 0xFFFF, 0, 0, 0]), t)

    def s_home_position(self, t):
        self.send(FC, self.m.MAVLink_home_position_message(
            int(HOME_LAT * 1e7), int(HOME_LON * 1e7), int(HOME_ALT * 1000), 0.0, 0.0, 0.0,
            [1.0, 0.0, 0.0, 0.0], 0.0, 0.0, 0.0, (t - BOOT_MS) * 1000 + UNIX_START_US), t)

    def s_rc_override(self, t):
        if not self.cc_in_control:
            return
        r, pi, th, ya = self.pilot_sticks()
        self.override = [r, pi, th, ya, 65535, 65535, 65535, 1750]
        self.send(CC, self.m.MAVLink_rc_channels_override_message(
            FC[0], FC[1], *(self.override + [0] * 10)), t)


def main():
    ap = argparse.ArgumentParser(
        description="Write a reproducible ArduPlane + FBWAG telemetry capture "
                    "(MAVLink frames made by pymavlink with the fbwag dialect).",
        epilog="The same arguments always give the same bytes. Examples:\n"
               "  make_telemetry.py -o flight.bin\n"
               "  make_telemetry.py --bytes 64K --v1-fraction 0.2 -o mixed.bin\n"
               "  make_telemetry.py --sign-key $(printf '%064x' 42) --tlog -o signed.tlog",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("-o", "--output", metavar="FILE", default="-",
                    help="output file (default: stdout, binary)")
    ap.add_argument("--bytes", metavar="N", type=parse_size, default=4 * 1024 * 1024,
                    help="target size: whole simulated seconds are generated until the output "
                         "reaches N bytes (suffixes K, M: 1024-based; default 4M = 4194304)")
    ap.add_argument("--seed", metavar="S", type=parse_seed, default=1,
                    help="seed for the flight (wind, RC-loss events, noise) (default 1)")
    ap.add_argument("--v1-fraction", metavar="F", type=parse_fraction, default=0.0,
                    help="share of frames with message id <= 255 sent as MAVLink 1 "
                         "(0..1, default 0); MAVLink 1 frames are never signed")
    ap.add_argument("--v1-extensions", choices=("keep", "drop"), default="keep",
                    help="MAVLink 1 frames: 'keep' extension fields as pymavlink does (default), "
                         "or 'drop' them as the C library / ArduPilot does")
    ap.add_argument("--sign-key", metavar="HEX64", type=parse_key, default=None,
                    help="sign every MAVLink 2 frame with this 32-byte key (pymavlink signing, "
                         "link id 0, timestamps from the simulated clock, starting 2025-06-01T09:00Z)")
    ap.add_argument("--mix", choices=("arduplane", "legacy"), default="arduplane",
                    help="'arduplane' (default): SRx-like stream rates and a 1,180-entry "
                         "parameter download (see the module doc); 'legacy': the benchmarks' "
                         "capture before that (faster streams, 87 parameters)")
    ap.add_argument("--tlog", action="store_true",
                    help="write pymavlink .tlog records: an 8-byte big-endian Unix time in "
                         "microseconds before each frame")
    args = ap.parse_args()

    if args.output == "-" and sys.stdout.isatty():
        ap.error("refusing to write binary to a terminal; use -o FILE or a pipe")

    started = time.perf_counter()   # for the summary only; never reaches the output
    mod = fbwag_dialect.load("2.0")
    link = Link(mod, args)
    rnd = Rand(args.seed)
    flight = Flight(mod, link, rnd, args.mix, args.seed)
    streams = flight.streams()
    plane = flight.plane

    t = BOOT_MS
    flight.connect(t)
    seconds = 0
    while len(link.out) < args.bytes:
        for _ in range(1000 // TICK_MS):
            flight.update(t)
            plane.step(TICK_MS / 1000.0)
            flight.baro_noise.step()
            for n in flight.imu_noise:
                n.step()
            for n in flight.gps_noise:
                n.step()
            flight.run_events(t)
            for name, ids, period, phase, fn in streams:
                if (t - phase) % period == 0:
                    fn(t)
            t += TICK_MS
        seconds += 1

    data = bytes(link.out)
    if args.output == "-":
        sys.stdout.buffer.write(data)
        sys.stdout.buffer.flush()
    else:
        with open(args.output, "wb") as f:
            f.write(data)
    print("make_telemetry: %d frames (%d MAVLink 1, %d signed), %d bytes%s, %d message types, "
          "%d simulated s, seed %d, %.1f s"
          % (link.frames, link.v1_frames, link.signed_frames, len(data),
             " (tlog)" if args.tlog else "", len(link.types), seconds, args.seed,
             time.perf_counter() - started), file=sys.stderr)
    if os.environ.get("MAKE_TELEMETRY_MIX"):
        for name in sorted(link.types, key=lambda k: (-link.types[k], k)):
            print("%8d %s" % (link.types[name], name), file=sys.stderr)


if __name__ == "__main__":
    try:
        main()
    except BrokenPipeError:
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        sys.exit(141)

//! fc-sim's ground-station services, carried out: what [`super::gcs`]
//! read out of a frame is answered here, with the daemon's model, streams,
//! parameters and engine at hand.

use super::gcs::{self, Command, Interval, Kind, Plan, Request, Stream};
use super::params::{Param, ParamError, Settings};
use super::remote_log;
use super::telemetry;
use super::{Daemon, ParamCursor, PARAM_LIST_INTERVAL};
use crate::live::net::Net;
use crate::live::Level;
use crate::live::Log;
use fbwag_delegation::fc::Authority;
use fbwag_delegation::{Moment, Peer};
use fbwag_dialect::dialects::common::{
    CommandAck, MavCmd, MavMissionResult, MavMissionType, MavResult, MavSeverity, MessageInterval,
    MissionAck, MissionCount, ParamValue, Statustext, Timesync,
};
use fbwag_dialect::mavframe::field::chars;
use fbwag_dialect::mavframe::Received;
use fbwag_dialect::Dialect;
use serde_json::json;

impl Daemon {
    /// Serves `frame` if it asks something of a ground-station service
    /// and the node lets it be served (`serve`: with signing required,
    /// only a frame whose signature verified).
    pub(super) fn serve_frame(
        &mut self,
        now: Moment,
        frame: &Received<'_, Dialect>,
        serve: bool,
        net: &mut Net<'_, '_>,
    ) {
        let h = frame.header();
        let from = Peer::new(h.sysid, h.compid);
        match gcs::classify(frame.frame(), self.own) {
            Kind::Request(_) if !serve => {
                self.refused_unsigned = self.refused_unsigned.saturating_add(1);
                self.gcs_log.log(net.log, Level::Warn, "GCS log lines", || {
                    format!(
                        "not served: unsigned {} from {}/{}",
                        frame.meta().map_or("request", |m| m.name),
                        from.sysid,
                        from.compid
                    )
                });
            }
            Kind::Request(r) => self.serve(now, r, from, net),
            Kind::Other => {}
            Kind::Unhandled => {
                let name = frame.meta().map_or_else(
                    || format!("MSG_ID_{}", frame.frame().msg_id()),
                    |m| m.name.to_string(),
                );
                self.not_served(name, from, net.log);
            }
        }
    }

    /// Counts something asked and not served; logs its first occurrence.
    fn not_served(&mut self, what: String, from: Peer, log: &mut Log) {
        if self.unhandled.note(what.clone()) {
            log.info(&format!(
                "not served: {what} from {}/{} (first; counted)",
                from.sysid, from.compid
            ));
        }
    }

    fn serve(&mut self, now: Moment, r: Request, from: Peer, net: &mut Net<'_, '_>) {
        match r {
            Request::Command(c) => self.command(now, c, from, net),
            Request::SetMode => {
                self.refusal(gcs::DENY_AUTHORITY, "SET_MODE", from, net);
                // ArduPilot acknowledges SET_MODE with SET_MODE's message id.
                self.ack(MavCmd(11), MavResult::DENIED, from, net);
            }
            Request::ParamList => {
                // A request while a list is going out restarts it, at the
                // same pace: repeating the request cannot speed it up.
                let due = self.param_list.map_or(now, |c| c.due.max(now));
                self.param_list = Some(ParamCursor {
                    index: 0,
                    due,
                    to: from,
                });
            }
            Request::ParamRead { index, id } => self.param_read(index, &id, from, net),
            Request::ParamSet { id, value } => self.param_set(now, &id, value, from, net),
            Request::DataStream {
                stream,
                rate_hz,
                start,
            } => {
                let rate = (start && rate_hz > 0).then_some(rate_hz);
                if !self.streams.set_group(stream, rate, now.0) {
                    let what = format!("REQUEST_DATA_STREAM({})", stream.0);
                    self.not_served(what, from, net.log);
                }
            }
            Request::MissionList(t) => self.mission_list(t, from, net),
            Request::MissionUpload {
                mission_type,
                count: 0,
            } => {
                let done = MavMissionResult::MAV_MISSION_ACCEPTED;
                self.mission_ack(mission_type, done, from, net)
            }
            Request::MissionUpload { mission_type, .. } => {
                self.mission_refused(mission_type, from, net)
            }
            Request::MissionItem(t) => {
                let invalid = MavMissionResult::MAV_MISSION_INVALID_SEQUENCE;
                self.mission_ack(t, invalid, from, net)
            }
            Request::MissionClear(t) => {
                let done = MavMissionResult::MAV_MISSION_ACCEPTED;
                self.mission_ack(t, done, from, net)
            }
            Request::SetupSigning { key, timestamp } => {
                self.setup_signing(now, key, timestamp, from, net)
            }
            Request::Timesync { ts1 } => {
                let tc1 = i64::try_from(now.0.saturating_mul(1000)).unwrap_or(i64::MAX);
                self.send(&Timesync { tc1, ts1 }, net);
            }
            Request::RemoteLog { seqno, ack } => self.remote_log(now, seqno, ack, from, net.log),
        }
    }

    /// A REMOTE_LOG_BLOCK_STATUS: the log over MAVLink begun, ended, or a
    /// block answered.
    fn remote_log(&mut self, now: Moment, seqno: u32, ack: bool, from: Peer, log: &mut Log) {
        let start = if seqno == remote_log::START {
            remote_log::start_bytes(now.0, self.mode_number())
        } else {
            Vec::new()
        };
        let was_client = self.flight_log.client() == Some(from);
        if self.flight_log.status(now.0, from, seqno, ack, &start) {
            log.info(&format!(
                "log: sending the DataFlash log to {}/{} (REMOTE_LOG_DATA_BLOCK)",
                from.sysid, from.compid
            ));
            self.log_due = now.0;
        } else if was_client && self.flight_log.client().is_none() {
            log.info(&format!("log: stopped by {}/{}", from.sysid, from.compid));
        }
    }

    fn command(&mut self, now: Moment, c: Command, from: Peer, net: &mut Net<'_, '_>) {
        let result = match gcs::plan(&c) {
            Plan::SendVersion => {
                self.send(&telemetry::autopilot_version(self.own), net);
                MavResult::ACCEPTED
            }
            Plan::SendOnce(s) => {
                self.send_stream(s, now, net);
                MavResult::ACCEPTED
            }
            Plan::SetInterval(s, i) => {
                let interval = match i {
                    Interval::Off => None,
                    Interval::Default => s.default_interval(),
                    Interval::Every(d) => Some(d),
                };
                self.streams.set(s, interval, now.0);
                MavResult::ACCEPTED
            }
            Plan::GetInterval(id) => {
                self.message_interval(id, net);
                MavResult::ACCEPTED
            }
            Plan::Nothing => MavResult::ACCEPTED,
            Plan::Deny(why) => {
                self.refusal(why, &format!("command {}", c.command.0), from, net);
                MavResult::DENIED
            }
            Plan::Invalid => MavResult::DENIED,
            Plan::Unsupported => {
                self.not_served(unsupported_command(&c), from, net.log);
                MavResult::UNSUPPORTED
            }
        };
        self.ack(c.command, result, from, net);
    }

    /// MESSAGE_INTERVAL for `id`: its interval, −1 if stopped, 0 if fc-sim
    /// never sends it.
    fn message_interval(&self, id: u16, net: &mut Net<'_, '_>) {
        let interval_us = match Stream::by_msg_id(f32::from(id)) {
            Some(s) => self
                .streams
                .interval(s)
                .map_or(-1, |d| i32::try_from(d.as_micros()).unwrap_or(i32::MAX)),
            None => 0,
        };
        let msg = MessageInterval {
            message_id: id,
            interval_us,
        };
        self.send(&msg, net);
    }

    fn ack(&self, command: MavCmd, result: MavResult, to: Peer, net: &mut Net<'_, '_>) {
        let ack = CommandAck {
            command,
            result,
            progress: 0,
            result_param2: 0,
            target_system: to.sysid,
            target_component: to.compid,
        };
        self.send(&ack, net);
    }

    /// Says why something was refused: in the log and, rate-limited, as a
    /// STATUSTEXT for the ground station's operator.
    pub(super) fn refusal(&mut self, why: &str, what: &str, from: Peer, net: &mut Net<'_, '_>) {
        self.gcs_log
            .log(net.log, Level::Notice, "GCS log lines", || {
                format!("refused {what} from {}/{}: {why}", from.sysid, from.compid)
            });
        if self.texts.admit().0 {
            let text = Statustext {
                severity: MavSeverity::WARNING,
                text: chars(why),
                id: 0,
                chunk_seq: 0,
            };
            self.send(&text, net);
        }
    }

    fn mission_list(&mut self, t: MavMissionType, to: Peer, net: &mut Net<'_, '_>) {
        let msg = MissionCount {
            target_system: to.sysid,
            target_component: to.compid,
            count: 0,
            mission_type: t,
        };
        self.send(&msg, net);
    }

    fn mission_refused(&mut self, t: MavMissionType, to: Peer, net: &mut Net<'_, '_>) {
        self.refusal(
            "missions not supported by fc-sim",
            "a mission upload",
            to,
            net,
        );
        let unsupported = MavMissionResult::MAV_MISSION_UNSUPPORTED;
        self.mission_ack(t, unsupported, to, net);
    }

    fn mission_ack(
        &self,
        t: MavMissionType,
        result: MavMissionResult,
        to: Peer,
        net: &mut Net<'_, '_>,
    ) {
        let msg = MissionAck {
            target_system: to.sysid,
            target_component: to.compid,
            r#type: result,
            mission_type: t,
        };
        self.send(&msg, net);
    }
}

// --- parameters ----------------------------------------------------------

impl Daemon {
    fn param_value(&self, p: Param) -> ParamValue {
        ParamValue {
            param_id: chars(p.name()),
            param_value: p.value(&self.settings),
            param_type: p.param_type(),
            param_count: Param::ALL.len() as u16,
            param_index: p.index(),
        }
    }

    pub(super) fn send_param_list(&mut self, now: Moment, net: &mut Net<'_, '_>) {
        let Some(cursor) = self.param_list else {
            return;
        };
        if now < cursor.due {
            return;
        }
        let Some(&p) = Param::ALL.get(cursor.index) else {
            self.param_list = None;
            net.log.info(&format!(
                "sent {} parameters to {}/{}",
                Param::ALL.len(),
                cursor.to.sysid,
                cursor.to.compid
            ));
            return;
        };
        self.send(&self.param_value(p), net);
        self.param_list = Some(ParamCursor {
            index: cursor.index + 1,
            due: now + PARAM_LIST_INTERVAL,
            to: cursor.to,
        });
    }

    fn param_read(&mut self, index: i16, id: &[u8; 16], from: Peer, net: &mut Net<'_, '_>) {
        let p = if index >= 0 {
            Param::by_index(i64::from(index))
        } else {
            Param::by_id(id)
        };
        match p {
            Some(p) => self.send(&self.param_value(p), net),
            // As ArduPilot: no answer for a parameter it does not have.
            None => self.not_served(
                unknown_param("PARAM_REQUEST_READ", index, id),
                from,
                net.log,
            ),
        }
    }

    fn param_set(
        &mut self,
        now: Moment,
        id: &[u8; 16],
        value: f32,
        from: Peer,
        net: &mut Net<'_, '_>,
    ) {
        let Some(p) = Param::by_id(id) else {
            return self.not_served(unknown_param("PARAM_SET", -1, id), from, net.log);
        };
        let result = self
            .forbids(p)
            .map_or(Ok(()), Err)
            .and_then(|()| p.apply(value, &self.settings));
        match result {
            Ok(settings) => self.reconfigure(now, p, settings, from, net.log),
            Err(e) => {
                let why = e.to_string();
                self.refusal(&why, &format!("PARAM_SET {value}"), from, net)
            }
        }
        // The answer either way: the value now in force.
        self.send(&self.param_value(p), net);
    }

    /// Why `p` may not change now: a parameter that decides who flies
    /// changes only on the ground (disarmed), and never during a handover.
    fn forbids(&self, p: Param) -> Option<ParamError> {
        if !p.is_protected() {
            return None;
        }
        if self.armed {
            return Some(ParamError::Armed(p));
        }
        self.busy().map(|mode| ParamError::Busy(p, mode))
    }

    /// The mode while a parameter change could disturb a handover: any
    /// time but the pilot flying with a working receiver and no notice
    /// still being retried.
    fn busy(&self) -> Option<&'static str> {
        let engine = self.node.engine();
        let a = engine.authority();
        let idle = a == Authority::Pilot
            && self.receiver_ok
            && engine.machine().receiver_ok()
            && engine.machine().poll_timeout().is_none();
        if idle {
            return None;
        }
        Some(match a {
            Authority::Pilot => "RC loss or hand-back",
            Authority::Handshake => "CIRCLE",
            Authority::Companion => "FBWAG",
            Authority::Rtl => "RTL",
        })
    }

    /// The new `settings` in force: a new engine for a new engine
    /// configuration, started now (the old one was idle, see
    /// [`Daemon::forbids`], so nothing of a handover is lost); the model's
    /// new airspeed.
    fn reconfigure(
        &mut self,
        now: Moment,
        p: Param,
        settings: Settings,
        from: Peer,
        log: &mut Log,
    ) {
        if settings == self.settings {
            return;
        }
        if settings.fc != self.settings.fc {
            if self.node.reconfigure(settings.fc, now).is_err() {
                // Param::apply validated it; keep the engine that runs.
                return;
            }
            self.node.set_receiver_ok(self.receiver_ok || !self.armed);
        }
        self.plane
            .set_cruise_airspeed(f64::from(settings.cruise_airspeed));
        self.settings = settings;
        let value = p.value(&settings);
        log.notice(&format!(
            "parameter {} = {value} (set by {}/{})",
            p.name(),
            from.sysid,
            from.compid
        ));
        self.events.emit(
            "param",
            json!({"name": p.name(), "value": value, "sysid": from.sysid, "compid": from.compid}),
        );
    }
}

/// How an unsupported command is counted: by command, and for the
/// message-interval and request-message commands by the message asked for.
fn unsupported_command(c: &Command) -> String {
    let kind = if c.int { "COMMAND_INT" } else { "COMMAND_LONG" };
    match c.command {
        MavCmd::GET_MESSAGE_INTERVAL | MavCmd::SET_MESSAGE_INTERVAL | MavCmd::REQUEST_MESSAGE => {
            format!("{kind}({} message {})", c.command.0, c.param1)
        }
        other => format!("{kind}({})", other.0),
    }
}

/// How an unknown parameter is counted: by name or index.
fn unknown_param(what: &str, index: i16, id: &[u8; 16]) -> String {
    if index >= 0 {
        return format!("{what}(index {index})");
    }
    let end = id.iter().position(|&b| b == 0).unwrap_or(id.len());
    let name: String = String::from_utf8_lossy(&id[..end])
        .chars()
        .map(|c| if c.is_ascii_graphic() { c } else { '?' })
        .collect();
    format!("{what}({name})")
}

//! mavlink-router's keys as fbwag's options: every key its documentation
//! (`examples/config.sample`) lists is carried out by an option of the
//! command line, or refused at its line with the reason. An endpoint
//! becomes a link named as its section (`[UdpEndpoint gcs]` →
//! `gcs=udpin:…`), in the order the sections were first opened, and the
//! TCP server (`TcpServerPort`) a `tcpin` link after them; per-endpoint
//! keys become the per-link options naming it (`--filter-out gcs:…`,
//! `--flow-control fc`). The words then go through clap like a TOML
//! file's ([`super::Given`]), so their values are checked where the
//! options check them.
//!
//! Where fbwag differs, on purpose (docs/deployment.md, "Migrating from
//! mavlink-router", has the table): no TCP server unless `TcpServerPort`
//! names its port (mavlink-router listens on 5760 on every interface by
//! default); `SnifferSysid` makes the links its system is heard on
//! sniffers (verified, where a link has a key); a list of baud rates,
//! `Group`, `RetryTimeout = 0` and PX4's log (`MavlinkDialect = common`
//! with `Log`) are refused.

use super::ini::{Document, Entry, Kind, Section};
use super::{ConfigError, Given, Value};
use crate::args::is_link_name;
use fbwag_delegation::node::MAX_LINKS;
use std::net::{IpAddr, Ipv6Addr};

/// The option the links go to: the router's positional `links` (the
/// companion takes them as `--out`).
pub const LINKS: &str = "links";

/// mavlink-router's baud rate when `Baud` is not given.
const DEFAULT_BAUD: u32 = 115_200;

/// The first port of a `Mode = Normal` endpoint without `Port`.
const FIRST_UDP_PORT: u16 = 14550;

/// Largest message id (24 bits in MAVLink 2).
const MAX_MSG_ID: u64 = (1 << 24) - 1;

/// The keys of `[General]`.
const GENERAL_KEYS: [&str; 12] = [
    "TcpServerPort",
    "ReportStats",
    "DebugLogLevel",
    "DeduplicationPeriod",
    "SnifferSysid",
    "MavlinkDialect",
    "Log",
    "LogMode",
    "LogSystemId",
    "MinFreeSpace",
    "MaxLogFiles",
    "LogTelemetry",
];

/// The keys of every endpoint, as a list for messages.
const FILTER_KEYS: &str = "AllowMsgIdOut, BlockMsgIdOut, AllowSrcCompOut, BlockSrcCompOut, AllowSrcSysOut, BlockSrcSysOut, AllowMsgIdIn, BlockMsgIdIn, AllowSrcCompIn, BlockSrcCompIn, AllowSrcSysIn, BlockSrcSysIn, Group";

/// The options `doc` stands for.
pub fn settings(doc: &Document) -> Result<Vec<Given>, ConfigError> {
    let mut out = Vec::new();
    let endpoints: Vec<&Section> = doc
        .sections
        .iter()
        .filter(|s| s.kind != Kind::General)
        .collect();
    check_names(&endpoints)?;
    let ports = udp_ports(&endpoints)?;
    for (section, port) in endpoints.iter().zip(ports) {
        endpoint(section, port, &mut out)?;
    }
    if let Some(general) = doc.sections.iter().find(|s| s.kind == Kind::General) {
        self::general(general, &mut out)?;
    }
    Ok(out)
}

/// One word for `option`, from `e`'s value.
fn given(option: &str, e: &Entry, word: impl Into<String>) -> Given {
    Given {
        option: option.to_string(),
        key: e.key.clone(),
        at: e.at.clone(),
        value: Value::Words(vec![(word.into(), e.value_at.clone())]),
    }
}

/// `e`'s value refused.
fn refuse(e: &Entry, why: impl Into<String>) -> ConfigError {
    ConfigError::Key {
        at: e.value_at.clone(),
        key: e.key.clone(),
        why: why.into(),
    }
}

/// `e` refused as a key: `why` it has no equivalent.
fn refuse_key(e: &Entry, why: impl Into<String>) -> ConfigError {
    ConfigError::Key {
        at: e.at.clone(),
        key: e.key.clone(),
        why: why.into(),
    }
}

/// An unsigned decimal number from `lo` to `hi`.
fn number(e: &Entry, lo: u64, hi: u64) -> Result<u64, ConfigError> {
    let v = e.value.as_str();
    v.parse::<u64>()
        .ok()
        .filter(|n| v.bytes().all(|b| b.is_ascii_digit()) && (lo..=hi).contains(n))
        .ok_or_else(|| refuse(e, format!("expected a number from {lo} to {hi}, not `{v}`")))
}

/// `true`/`false` (any case) or `1`/`0`, as mavlink-router's booleans.
fn boolean(e: &Entry) -> Result<bool, ConfigError> {
    match e.value.to_ascii_lowercase().as_str() {
        "true" | "1" => Ok(true),
        "false" | "0" => Ok(false),
        v => Err(refuse(
            e,
            format!("expected true, false, 1 or 0, not `{v}`"),
        )),
    }
}

/// One of `words` (any case), lowercased.
fn one_of(e: &Entry, words: &[&str]) -> Result<String, ConfigError> {
    let v = e.value.to_ascii_lowercase();
    if words.contains(&v.as_str()) {
        Ok(v)
    } else {
        Err(refuse(
            e,
            format!("expected one of {}, not `{}`", words.join(", "), e.value),
        ))
    }
}

/// Every endpoint's name must name an fbwag link, once.
fn check_names(endpoints: &[&Section]) -> Result<(), ConfigError> {
    for (i, s) in endpoints.iter().enumerate() {
        let name = s.name.as_deref().unwrap_or_default();
        let fault = |why: String| ConfigError::Key {
            at: s.at.clone(),
            key: s.title(),
            why,
        };
        if i == MAX_LINKS {
            return Err(fault(format!(
                "more than {MAX_LINKS} endpoints: a router has {MAX_LINKS} links at most"
            )));
        }
        if !is_link_name(name) {
            return Err(fault(format!(
                "`{name}` cannot name a link: a letter, then letters, digits, `_` and `-`, {} characters at most, and not a connection scheme (udpin, serial, …)",
                crate::args::MAX_NAME
            )));
        }
        if let Some(other) = endpoints[..i]
            .iter()
            .find(|o| o.name.as_deref() == Some(name))
        {
            return Err(fault(format!(
                "{} is named `{name}` too: a name names one link",
                other.title()
            )));
        }
    }
    Ok(())
}

/// The port of each endpoint, where it is a UDP one in normal mode
/// without `Port`: the lowest from 14550 that no other such endpoint to
/// the same address uses, given in the order mavlink-router gives them
/// (its sections come last first).
fn udp_ports(endpoints: &[&Section]) -> Result<Vec<Option<u16>>, ConfigError> {
    let mut ports = vec![None; endpoints.len()];
    let normal = |s: &Section| {
        s.kind == Kind::Udp
            && s.get("Mode")
                .is_some_and(|m| m.value.eq_ignore_ascii_case("normal"))
    };
    let mut taken: Vec<(String, u16)> = Vec::new();
    for s in endpoints.iter().filter(|s| normal(s)) {
        if let (Some(address), Some(port)) = (s.get("Address"), s.get("Port")) {
            let port = number(port, 1, u64::from(u16::MAX))? as u16;
            taken.push((address.value.clone(), port));
        }
    }
    for (i, s) in endpoints.iter().enumerate().rev() {
        let (Some(address), None) = (s.get("Address"), s.get("Port")) else {
            continue;
        };
        if !normal(s) {
            continue;
        }
        let free = (FIRST_UDP_PORT..=u16::MAX)
            .find(|p| !taken.contains(&(address.value.clone(), *p)))
            .ok_or_else(|| refuse(address, "no free UDP port left from 14550"))?;
        taken.push((address.value.clone(), free));
        ports[i] = Some(free);
    }
    Ok(ports)
}

/// The logging keys of `[General]`, carried out together: the others
/// need `Log`.
#[derive(Default)]
struct LogKeys<'a> {
    dir: Option<&'a Entry>,
    telemetry: Option<&'a Entry>,
    dialect: Option<&'a Entry>,
    /// Keys that apply to the logs of `Log`.
    needing_dir: Vec<&'a Entry>,
}

/// The keys of `[General]`.
fn general(s: &Section, out: &mut Vec<Given>) -> Result<(), ConfigError> {
    let mut logs = LogKeys::default();
    for e in &s.entries {
        general_key(e, &mut logs, out)?;
    }
    logs.carry_out(out)
}

/// One key of `[General]`: its option, or kept in `logs`.
fn general_key<'a>(
    e: &'a Entry,
    logs: &mut LogKeys<'a>,
    out: &mut Vec<Given>,
) -> Result<(), ConfigError> {
    let word = match e.key.to_ascii_lowercase().as_str() {
        "tcpserverport" => match number(e, 0, u64::from(u16::MAX))? {
            0 => None,
            port => Some((LINKS, format!("tcpin:0.0.0.0:{port}"))),
        },
        "reportstats" => Some(("report", if boolean(e)? { "10" } else { "off" }.into())),
        "debugloglevel" => {
            let level = match one_of(e, &["error", "warning", "info", "debug", "trace"])?.as_str() {
                "error" => "error",
                "warning" => "warn",
                "info" => "info",
                _ => "debug",
            };
            Some(("log-level", level.into()))
        }
        "deduplicationperiod" => Some(("dedup", number(e, 0, u64::MAX)?.to_string())),
        "sniffersysid" => match number(e, 0, 255)? {
            0 => None,
            id => Some(("sniffer-sysid", id.to_string())),
        },
        "mavlinkdialect" => {
            one_of(e, &["auto", "common", "ardupilotmega"])?;
            logs.dialect = Some(e);
            None
        }
        "log" => {
            logs.dir = Some(e);
            None
        }
        "logtelemetry" => {
            logs.telemetry = boolean(e)?.then_some(e);
            None
        }
        key => {
            let word = match key {
                "logmode" => ("log-mode", one_of(e, &["always", "while-armed"])?),
                "logsystemid" => ("log-sysid", number(e, 1, 255)?.to_string()),
                "minfreespace" => ("tlog-min-free", number(e, 0, u64::MAX)?.to_string()),
                "maxlogfiles" => ("log-max-files", number(e, 0, u32::MAX.into())?.to_string()),
                _ => {
                    let keys = GENERAL_KEYS.join(", ");
                    let why = format!("not a key of [General]; its keys: {keys}");
                    return Err(refuse_key(e, why));
                }
            };
            logs.needing_dir.push(e);
            Some(word)
        }
    };
    if let Some((option, word)) = word {
        out.push(given(option, e, word));
    }
    Ok(())
}

impl LogKeys<'_> {
    /// `Log` as `--flight-log`, `LogTelemetry` as `--tlog` in the same
    /// directory; refused: a key that needs `Log` without it, PX4's log.
    fn carry_out(self, out: &mut Vec<Given>) -> Result<(), ConfigError> {
        let Some(dir) = self.dir else {
            if let Some(e) = self.telemetry.or(self.needing_dir.first().copied()) {
                return Err(refuse_key(
                    e,
                    "applies to the logs of `Log`, which is not given: give Log (their directory)",
                ));
            }
            return Ok(());
        };
        if let Some(e) = self
            .dialect
            .filter(|e| e.value.eq_ignore_ascii_case("common"))
        {
            return Err(refuse(
                e,
                "with Log, `common` means PX4's ULog (LOGGING_DATA), which fbwag does not receive: it receives ArduPilot's DataFlash log (ardupilotmega or auto)",
            ));
        }
        out.push(given("flight-log", dir, dir.value.clone()));
        if let Some(e) = self.telemetry {
            out.push(Given {
                value: Value::Words(vec![(dir.value.clone(), e.value_at.clone())]),
                ..given("tlog", e, "")
            });
        }
        Ok(())
    }
}

/// An endpoint: its link and its per-link options. `port`: the port
/// [`udp_ports`] chose, where it chose one.
fn endpoint(s: &Section, port: Option<u16>, out: &mut Vec<Given>) -> Result<(), ConfigError> {
    let name = s.name.clone().unwrap_or_default();
    for e in &s.entries {
        let key = e.key.to_ascii_lowercase();
        if let Some((option, rule)) = filter(&key, s.kind) {
            let list = id_list(e, rule)?;
            out.push(given(option, e, format!("{name}:{rule}={list}")));
            continue;
        }
        match (s.kind, key.as_str()) {
            (_, "group") => {
                return Err(refuse_key(
                    e,
                    "no equivalent: fbwag keeps no shared list of systems for a group of links; a frame goes to every link but the one it came on, so give redundant links DeduplicationPeriod (their copies are routed once)",
                ))
            }
            (Kind::Uart, "flowcontrol") => {
                if boolean(e)? {
                    out.push(given("flow-control", e, name.clone()));
                }
            }
            // fbwag opens a failed link again every second.
            (Kind::Tcp, "retrytimeout") => {
                if number(e, 0, i32::MAX as u64)? == 0 {
                    return Err(refuse(
                        e,
                        "0 (never reconnect) has no equivalent: fbwag opens a link that fails again every second",
                    ));
                }
            }
            (Kind::Uart, "device" | "baud") | (Kind::Udp, "address" | "mode" | "port") => {}
            (Kind::Tcp, "address" | "port") => {}
            _ => return Err(refuse_key(e, unknown_key(s.kind))),
        }
    }
    let (conn, at) = conn(s, port)?;
    out.push(Given {
        value: Value::Words(vec![(format!("{name}={conn}"), at.value_at.clone())]),
        ..given(LINKS, at, "")
    });
    Ok(())
}

/// An endpoint's connection string, and the key it is blamed on (its
/// address or device).
fn conn(s: &Section, port: Option<u16>) -> Result<(String, &Entry), ConfigError> {
    let missing = |key: &str| ConfigError::Key {
        at: s.at.clone(),
        key: s.title(),
        why: format!("`{key}` is required"),
    };
    let needed = |key: &str| s.get(key).ok_or_else(|| missing(key));
    match s.kind {
        Kind::Uart => {
            let device = needed("Device")?;
            let baud = match s.get("Baud") {
                Some(e) => baud(e)?,
                None => DEFAULT_BAUD,
            };
            Ok((format!("serial:{}:{baud}", device.value), device))
        }
        Kind::Udp => {
            let (address, mode) = (needed("Address")?, needed("Mode")?);
            let ip = ip(address)?;
            let scheme = udp_scheme(mode, address, ip)?;
            let port = match (s.get("Port"), port) {
                (Some(p), _) => number(p, 1, u64::from(u16::MAX))? as u16,
                (None, Some(p)) => p,
                (None, None) => return Err(missing("Port (in server mode)")),
            };
            Ok((format!("{scheme}:{}", socket(ip, port)), address))
        }
        Kind::Tcp | Kind::General => {
            let (address, p) = (needed("Address")?, needed("Port")?);
            let ip = ip(address)?;
            if ip.is_unspecified() || ip.is_multicast() {
                return Err(refuse(address, "a server's address to connect to"));
            }
            let port = number(p, 1, u64::from(u16::MAX))? as u16;
            Ok((format!("tcp:{}", socket(ip, port)), address))
        }
    }
}

fn unknown_key(kind: Kind) -> String {
    let own = match kind {
        Kind::Uart => "Device, Baud, FlowControl",
        Kind::Udp => "Mode, Address, Port, Filter",
        Kind::Tcp => "Address, Port, RetryTimeout",
        Kind::General => "",
    };
    format!(
        "not a key of [{} NAME]; its keys: {own}, {FILTER_KEYS}",
        kind.word()
    )
}

/// The filter option and rule of a filter key (lowercase), if it is one:
/// `allowmsgidout` is `--filter-out …:allow-msg=…`; UDP's legacy
/// `Filter` is `AllowMsgIdOut`.
fn filter(key: &str, kind: Kind) -> Option<(&'static str, &'static str)> {
    if kind == Kind::Udp && key == "filter" {
        return Some(("filter-out", "allow-msg"));
    }
    let (allow, rest) = match key {
        k if k.starts_with("allow") => (true, &k[5..]),
        k if k.starts_with("block") => (false, &k[5..]),
        _ => return None,
    };
    let (what, direction) = match rest {
        "msgidin" => ("msg", "filter-in"),
        "msgidout" => ("msg", "filter-out"),
        "srcsysin" => ("sys", "filter-in"),
        "srcsysout" => ("sys", "filter-out"),
        "srccompin" => ("comp", "filter-in"),
        "srccompout" => ("comp", "filter-out"),
        _ => return None,
    };
    let rule = match (allow, what) {
        (true, "msg") => "allow-msg",
        (false, "msg") => "block-msg",
        (true, "sys") => "allow-sys",
        (false, "sys") => "block-sys",
        (true, _) => "allow-comp",
        (false, _) => "block-comp",
    };
    Some((direction, rule))
}

/// A filter's list (comma-separated integers: message ids, or system or
/// component ids), checked, as fbwag writes it.
fn id_list(e: &Entry, rule: &str) -> Result<String, ConfigError> {
    let max = if rule.ends_with("msg") {
        MAX_MSG_ID
    } else {
        255
    };
    let mut ids = Vec::new();
    for item in e.value.split(',') {
        let item = item.trim();
        match item.parse::<u64>() {
            Ok(n) if n <= max && item.bytes().all(|b| b.is_ascii_digit()) => ids.push(n),
            _ => {
                return Err(refuse(
                    e,
                    format!(
                        "expected a comma-separated list of numbers from 0 to {max}, not `{item}`"
                    ),
                ))
            }
        }
    }
    Ok(ids.iter().map(u64::to_string).collect::<Vec<_>>().join(","))
}

/// `Baud`: one rate (mavlink-router's list, cycled until MAVLink is
/// heard, is refused: fbwag opens the port at one rate).
fn baud(e: &Entry) -> Result<u32, ConfigError> {
    if e.value.contains(',') {
        return Err(refuse(
            e,
            "a list of rates (cycled by mavlink-router until MAVLink is heard) has no equivalent: fbwag opens a serial port at one rate; give the rate of the flight controller's port (ArduPilot's SERIALn_BAUD)",
        ));
    }
    Ok(number(e, 1, u64::from(u32::MAX))? as u32)
}

/// An IP address: IPv4, or IPv6 in brackets.
fn ip(e: &Entry) -> Result<IpAddr, ConfigError> {
    let v = e.value.as_str();
    let parsed = match v.strip_prefix('[').and_then(|r| r.strip_suffix(']')) {
        Some(inner) => inner.parse::<Ipv6Addr>().ok().map(IpAddr::V6),
        None => v.parse::<std::net::Ipv4Addr>().ok().map(IpAddr::V4),
    };
    parsed.ok_or_else(|| {
        refuse(
            e,
            format!("expected an IP address (IPv6 in brackets: [::1]), not `{v}`"),
        )
    })
}

/// `IP:PORT`, IPv6 in brackets.
fn socket(ip: IpAddr, port: u16) -> String {
    std::net::SocketAddr::new(ip, port).to_string()
}

/// The scheme of a UDP endpoint: `server` listens (`udpin`), `normal`
/// sends to its address (`udpout`), or broadcasts until answered
/// (`udpbcast`) when the address is an IPv4 broadcast one.
fn udp_scheme(mode: &Entry, address: &Entry, ip: IpAddr) -> Result<&'static str, ConfigError> {
    match one_of(mode, &["normal", "server", "eavesdropping"])?.as_str() {
        "normal" => match ip {
            IpAddr::V4(v4) if v4.is_broadcast() || v4.octets()[3] == 255 => Ok("udpbcast"),
            ip if ip.is_multicast() => Err(refuse(
                address,
                "a multicast group: fbwag joins none; give a unicast or an IPv4 broadcast address",
            )),
            ip if ip.is_unspecified() => Err(refuse(
                address,
                "normal mode sends to this address: give the one to send to",
            )),
            _ => Ok("udpout"),
        },
        _ => Ok("udpin"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    fn map(text: &str) -> Result<Vec<(String, String)>, ConfigError> {
        let mut doc = Document::default();
        doc.read(Path::new("main.conf"), text)?;
        Ok(settings(&doc)?
            .into_iter()
            .map(|g| match g.value {
                Value::Words(w) => (g.option.to_string(), w[0].0.clone()),
                Value::Switch(on) => (g.option.to_string(), on.to_string()),
            })
            .collect())
    }

    fn refused(text: &str) -> (usize, String) {
        match map(text).unwrap_err() {
            ConfigError::Key { at, key, why } => (at.line, format!("{key}: {why}")),
            other => panic!("{other}"),
        }
    }

    fn pair(option: &str, word: &str) -> (String, String) {
        (option.to_string(), word.to_string())
    }

    #[test]
    fn endpoints_become_named_links_with_their_options() {
        let got = map(
            "[UartEndpoint fc]\nDevice=/dev/ttyS0\nFlowControl=1\nBlockMsgIdIn = 76, 11\n\
             [UdpEndpoint gcs]\nMode=Normal\nAddress=10.0.0.2\nFilter=0,30\n\
             [UdpEndpoint b]\nMode=normal\nAddress=192.168.1.255\nPort=14551\n\
             [UdpEndpoint s]\nMode=Eavesdropping\nAddress=[::]\nPort=9\nAllowSrcSysOut=1\n\
             [TcpEndpoint t]\nAddress=127.0.0.1\nPort=5761\nRetryTimeout=10\n\
             [General]\nTcpServerPort=5760\n",
        )
        .unwrap();
        assert_eq!(
            got,
            [
                pair("flow-control", "fc"),
                pair("filter-in", "fc:block-msg=76,11"),
                pair("links", "fc=serial:/dev/ttyS0:115200"),
                pair("filter-out", "gcs:allow-msg=0,30"),
                pair("links", "gcs=udpout:10.0.0.2:14550"),
                pair("links", "b=udpbcast:192.168.1.255:14551"),
                pair("filter-out", "s:allow-sys=1"),
                pair("links", "s=udpin:[::]:9"),
                pair("links", "t=tcp:127.0.0.1:5761"),
                pair("links", "tcpin:0.0.0.0:5760"),
            ]
        );
    }

    #[test]
    fn normal_endpoints_without_a_port_take_the_next_free_one_last_first() {
        let got = map("[UdpEndpoint a]\nMode=Normal\nAddress=127.0.0.1\n\
             [UdpEndpoint b]\nMode=Normal\nAddress=127.0.0.1\n\
             [UdpEndpoint c]\nMode=Normal\nAddress=127.0.0.1\nPort=14550\n\
             [UdpEndpoint d]\nMode=Normal\nAddress=10.0.0.1\n")
        .unwrap();
        let links: Vec<&str> = got.iter().map(|(_, w)| w.as_str()).collect();
        assert_eq!(
            links,
            [
                "a=udpout:127.0.0.1:14552",
                "b=udpout:127.0.0.1:14551",
                "c=udpout:127.0.0.1:14550",
                "d=udpout:10.0.0.1:14550",
            ]
        );
    }

    #[test]
    fn general_keys_become_options() {
        let got = map("[General]\nReportStats=false\nDebugLogLevel=Warning\n\
             DeduplicationPeriod=200\nSnifferSysid=254\nMavlinkDialect=ArduPilotMega\n\
             Log=/var/log/fs\nLogMode=While-Armed\nLogSystemId=1\nMinFreeSpace=1000\n\
             MaxLogFiles=5\nLogTelemetry=true\nTcpServerPort=0\n")
        .unwrap();
        assert_eq!(
            got,
            [
                pair("report", "off"),
                pair("log-level", "warn"),
                pair("dedup", "200"),
                pair("sniffer-sysid", "254"),
                pair("log-mode", "while-armed"),
                pair("log-sysid", "1"),
                pair("tlog-min-free", "1000"),
                pair("log-max-files", "5"),
                pair("flight-log", "/var/log/fs"),
                pair("tlog", "/var/log/fs"),
            ]
        );
    }

    #[test]
    fn keys_without_an_equivalent_are_refused_with_the_reason() {
        let cases: &[(&str, usize, &str)] = &[
            ("[UartEndpoint a]\nDevice=/dev/x\nBaud=57600,115200\n", 3, "one rate"),
            ("[UdpEndpoint a]\nMode=server\nAddress=0.0.0.0\nPort=1\nGroup=g\n", 5, "Group"),
            ("[TcpEndpoint a]\nAddress=127.0.0.1\nPort=1\nRetryTimeout=0\n", 4, "every second"),
            ("[General]\nMavlinkDialect=common\nLog=/x\n", 2, "ULog"),
            ("[General]\nMaxLogFiles=3\n", 2, "give Log"),
            ("[General]\nLogTelemetry=1\n", 2, "give Log"),
            ("[General]\nFoo=1\n", 2, "TcpServerPort"),
            ("[UdpEndpoint a]\nMode=server\nAddress=0.0.0.0\nPort=1\nBaud=1\n", 5, "not a key"),
            ("[UdpEndpoint a]\nMode=client\nAddress=0.0.0.0\nPort=1\n", 2, "normal"),
            ("[UdpEndpoint a]\nMode=weird\nAddress=0.0.0.0\n", 2, "not `weird`"),
            ("[UdpEndpoint a]\nMode=server\nAddress=0.0.0.0\n", 1, "`Port (in server mode)` is required"),
            ("[UdpEndpoint a]\nMode=normal\nAddress=224.0.0.1\n", 3, "multicast"),
            ("[UdpEndpoint a]\nMode=normal\nAddress=::1\nPort=2\n", 3, "in brackets"),
            ("[UdpEndpoint a]\nMode=server\nAddress=0.0.0.0\nPort=70000\n", 4, "65535"),
            ("[TcpEndpoint a]\nAddress=10.0.0.1\n", 1, "`Port` is required"),
            ("[UartEndpoint a]\nBaud=1\n", 1, "`Device` is required"),
            ("[UartEndpoint a]\nDevice=/x\nAllowSrcSysIn=1,256\n", 3, "`256`"),
            ("[UartEndpoint a]\nDevice=/x\nAllowMsgIdIn=1,,2\n", 3, "``"),
            ("[UartEndpoint a]\nDevice=/x\nFlowControl=yes\n", 3, "true, false"),
            ("[General]\nSnifferSysid=256\n", 2, "0 to 255"),
            ("[UdpEndpoint 1st]\nMode=server\nAddress=0.0.0.0\nPort=1\n", 1, "cannot name"),
            ("[UdpEndpoint serial]\nMode=server\nAddress=0.0.0.0\nPort=1\n", 1, "cannot name"),
            (
                "[UdpEndpoint a]\nMode=server\nAddress=0.0.0.0\nPort=1\n[TcpEndpoint a]\nAddress=1.1.1.1\nPort=1\n",
                5,
                "too",
            ),
        ];
        for (text, line, says) in cases {
            let (l, why) = refused(text);
            assert_eq!(l, *line, "{text:?}: {why}");
            assert!(why.contains(says), "{text:?}: {why}");
        }
    }
}

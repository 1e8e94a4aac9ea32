//! Links named on the command line: `NAME=CONN` gives a link a name, and
//! every option that takes a link (`LINK:RULE`, `[LINK:]KEY`, `--sniffer
//! LINK`, …) takes its name or its place among the links given (from 1).
//! A name stays with its link when a config directory adds a file; a place
//! does not.

use super::{routed_rate, sign_key, ArgError, RoutedRate, MAX_LINKS};
use fbwag_delegation::control::Control;
use fbwag_delegation::node::{Direction, Filter, FilterError, FilterRules};
use std::fmt;
use std::net::SocketAddr;

/// Words that name no link: connection schemes, and words a per-link
/// option's value begins with (`passphrase:TEXT`), so that `WORD:…` is
/// never read as a link's name.
const RESERVED: [&str; 9] = [
    "udpin",
    "udpout",
    "udpbcast",
    "tcp",
    "tcpin",
    "tcpout",
    "serial",
    "file",
    "passphrase",
];

/// Longest link name.
pub const MAX_NAME: usize = 32;

/// Whether `s` can name a link: a letter, then letters, digits, `_` and
/// `-`, 32 characters at most, and not a word of [`RESERVED`].
pub fn is_link_name(s: &str) -> bool {
    let mut chars = s.chars();
    chars.next().is_some_and(|c| c.is_ascii_alphabetic())
        && chars.all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
        && s.len() <= MAX_NAME
        && !RESERVED.contains(&s.to_ascii_lowercase().as_str())
}

/// `NAME=CONN`'s name, if any, and the connection string.
pub fn split_link_name(s: &str) -> (Option<&str>, &str) {
    match s.split_once('=') {
        Some((name, conn)) if is_link_name(name.trim()) => (Some(name.trim()), conn.trim()),
        _ => (None, s.trim()),
    }
}

/// A link as an option names it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum LinkRef {
    /// Its place among the links given, from 1.
    Place(usize),
    /// The name it was given (`NAME=CONN`).
    Name(String),
}

impl fmt::Display for LinkRef {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            LinkRef::Place(n) => write!(f, "{n}"),
            LinkRef::Name(name) => f.write_str(name),
        }
    }
}

impl LinkRef {
    /// The link's 0-based index among links named `names` (`None`: a link
    /// without a name).
    pub fn index(&self, names: &[Option<String>]) -> Result<usize, LinkOptionError> {
        match self {
            LinkRef::Place(n) => {
                n.checked_sub(1)
                    .filter(|i| *i < names.len())
                    .ok_or(LinkOptionError::NoSuchLink {
                        link: *n,
                        links: names.len(),
                    })
            }
            LinkRef::Name(name) => names
                .iter()
                .position(|n| n.as_deref() == Some(name))
                .ok_or_else(|| LinkOptionError::NoSuchName {
                    name: name.clone(),
                    names: names
                        .iter()
                        .flatten()
                        .cloned()
                        .collect::<Vec<_>>()
                        .join(", "),
                }),
        }
    }
}

/// `LINK`: a place (1 to [`MAX_LINKS`]) or a name.
fn link_ref(s: &str) -> Option<LinkRef> {
    let s = s.trim();
    match s.parse::<usize>() {
        Ok(n) => (1..=MAX_LINKS).contains(&n).then_some(LinkRef::Place(n)),
        Err(_) => is_link_name(s).then(|| LinkRef::Name(s.to_string())),
    }
}

/// `--sniffer LINK`: a link's place (from 1) or name.
pub fn link(s: &str) -> Result<LinkRef, ArgError> {
    link_ref(s).ok_or(ArgError::Link)
}

/// `LINK:REST`: the link and what follows it.
fn link_place(s: &str) -> Option<(LinkRef, &str)> {
    let (link, rest) = s.split_once(':')?;
    Some((link_ref(link)?, rest))
}

/// A value of an option given per link: `LINK:VALUE` for that link, or
/// `VALUE` alone for every link without its own.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ForLink<T> {
    /// The link; `None`: every link.
    pub link: Option<LinkRef>,
    pub value: T,
}

impl<T> ForLink<T> {
    /// `[LINK:]VALUE`, VALUE read by `parse`. (A value never starts with
    /// a link and a colon: hex digits, `@PATH`, an IPv4 address have none;
    /// an IPv6 one is in brackets; `passphrase:` is no link's name.)
    fn parse(s: &str, parse: impl Fn(&str) -> Result<T, ArgError>) -> Result<Self, ArgError> {
        let (link, value) = match link_place(s) {
            Some((link, value)) => (Some(link), value),
            None => (None, s),
        };
        Ok(ForLink {
            link,
            value: parse(value)?,
        })
    }

    /// The option and value as given, for an error.
    fn arg(&self, flag: &str) -> String {
        self.link
            .as_ref()
            .map_or(flag.to_string(), |l| format!("{flag} {l}"))
    }
}

/// `[LINK:]KEY`: a signing key (see [`sign_key`]), for one link or all.
pub fn link_sign_key(s: &str) -> Result<ForLink<String>, ArgError> {
    ForLink::parse(s, sign_key)
}

/// `[LINK:]IP:PORT`: a peer address, for one link or all.
pub fn link_peer(s: &str) -> Result<ForLink<SocketAddr>, ArgError> {
    ForLink::parse(s, |v| v.trim().parse().map_err(|_| ArgError::Address))
}

/// `fbwag router --routed-rate LINK:RATE`: the pace of what is routed to
/// that link, both checked as they are read; LINK is required.
pub fn link_rate(s: &str) -> Result<ForLink<RoutedRate>, ArgError> {
    let (link, rate) = link_place(s).ok_or(ArgError::LinkRate)?;
    Ok(ForLink {
        link: Some(link),
        value: routed_rate(rate)?,
    })
}

/// Each link's value of option `flag` from what was `given`, over links
/// named `names`: the link's own, else the one given for every link, else
/// none. A later value replaces an earlier one for the same link (or for
/// every link), as single-valued options do: a `--config` file's come
/// first, so the command line's win.
pub fn per_link<T: Clone>(
    flag: &str,
    given: &[ForLink<T>],
    names: &[Option<String>],
) -> Result<Vec<Option<T>>, (String, LinkOptionError)> {
    let mut every: Option<T> = None;
    let mut own: Vec<Option<T>> = vec![None; names.len()];
    for g in given {
        let slot = match &g.link {
            None => &mut every,
            Some(link) => {
                let i = link.index(names).map_err(|e| (g.arg(flag), e))?;
                &mut own[i]
            }
        };
        *slot = Some(g.value.clone());
    }
    Ok(own
        .into_iter()
        .map(|v| v.or_else(|| every.clone()))
        .collect())
}

/// The 0-based indices of `links` among links named `names`; `flag` names
/// the option in an error.
pub fn link_indices(
    flag: &str,
    links: &[LinkRef],
    names: &[Option<String>],
) -> Result<Vec<usize>, (String, LinkOptionError)> {
    links
        .iter()
        .map(|l| l.index(names).map_err(|e| (format!("{flag} {l}"), e)))
        .collect()
}

/// A rule of `--filter-in`/`--filter-out`: `LINK:RULE`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LinkRule {
    /// The link.
    pub link: LinkRef,
    /// The rule, as given (it parses).
    pub rule: String,
}

/// `LINK:RULE`, the rule checked as it is read (see
/// `fbwag_delegation::node::FilterRules::parse`).
pub fn link_rule(s: &str) -> Result<LinkRule, ArgError> {
    let (link, rule) = link_place(s).ok_or(ArgError::LinkRule)?;
    FilterRules::new().parse(rule)?;
    Ok(LinkRule {
        link,
        rule: rule.trim().to_string(),
    })
}

/// The filter of one direction of one link, from the rules given for it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LinkFilter {
    /// The link's place among the links it numbers, from 0.
    pub index: usize,
    /// Which way.
    pub direction: Direction,
    /// The filter.
    pub filter: Filter,
    /// Its rules as given, for the log.
    pub rules: Vec<String>,
}

/// Why options given per link (filters, keys, peers, paces) cannot
/// apply, or links cannot be named so.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum LinkOptionError {
    /// A value for a link past the last one given.
    #[error("link {link}: {} (counted from 1)", match links { 1 => "there is 1 link".to_string(), n => format!("there are {n} links") })]
    NoSuchLink { link: usize, links: usize },
    /// A value for a link no link is named.
    #[error("no link is named {name} ({})", if names.is_empty() { "none is: name one NAME=CONN".to_string() } else { format!("names: {names}") })]
    NoSuchName { name: String, names: String },
    /// Two links given one name.
    #[error("two links are named {0}: a name names one link")]
    NameTwice(String),
    /// Rules that together do not make a filter (too many message ids).
    #[error(transparent)]
    Rules(#[from] FilterError),
    /// A peer for a link that answers its target or its stream only.
    #[error("link {0} does not listen: a peer is for udpin and tcpin links")]
    NotListening(String),
    /// Port 0 (any port) for a link that sends to one address.
    #[error("a udpin link sends to one port: IP:0 (any port of IP) is for tcpin links")]
    AnyPort,
    /// A rule blocking the autonomy's control message: the handover, not
    /// a filter, decides where that goes.
    #[error("the autonomy's {0} is never filtered: the handover gates it (leave out --autonomy to keep any program from steering)")]
    AutonomyControl(&'static str),
    /// A serial port's option for a link that is no serial port.
    #[error("link {0} is no serial port")]
    NotSerial(String),
    /// An IPv6 peer for a link that listens on IPv4: it can never speak.
    #[error("link {0} listens on IPv4: an IPv6 peer can never reach it")]
    OtherFamily(String),
}

/// The names of links given as `[NAME=]CONN` (`None` for those without),
/// each name once; `flag` names the option of an error.
pub fn link_names<'a>(
    flag: &str,
    given: impl IntoIterator<Item = &'a str>,
) -> Result<Vec<Option<String>>, (String, LinkOptionError)> {
    let mut names: Vec<Option<String>> = Vec::new();
    for conn in given {
        let name = split_link_name(conn).0.map(str::to_string);
        if let Some(n) = name
            .as_ref()
            .filter(|n| names.contains(&Some(n.to_string())))
        {
            return Err((
                format!("{flag} {conn}"),
                LinkOptionError::NameTwice(n.clone()),
            ));
        }
        names.push(name);
    }
    Ok(names)
}

/// `--peer` values where they apply: a listening link (`udpin`, `tcpin`);
/// `IP:0`, any port of IP, on `tcpin` only (a datagram needs a port). A
/// value for every link applies to the listening ones.
pub fn check_peers(
    given: &[ForLink<SocketAddr>],
    endpoints: &[fbwag_dialect::Endpoint],
    names: &[Option<String>],
) -> Result<(), (String, LinkOptionError)> {
    use fbwag_dialect::mavframe::conn::Address;
    use fbwag_dialect::Endpoint;
    for g in given {
        let arg = || g.arg("--peer");
        let on: Vec<&Endpoint> = match &g.link {
            Some(link) => {
                let i = link.index(names).map_err(|e| (arg(), e))?;
                endpoints.get(i).into_iter().collect()
            }
            None => endpoints.iter().collect(),
        };
        for endpoint in on {
            match endpoint {
                Endpoint::UdpIn(_) if g.value.port() == 0 => {
                    return Err((arg(), LinkOptionError::AnyPort))
                }
                Endpoint::UdpIn(Address::Ip(at)) | Endpoint::TcpIn(Address::Ip(at))
                    if at.is_ipv4() && g.value.is_ipv6() =>
                {
                    let link = endpoint.to_string();
                    return Err((arg(), LinkOptionError::OtherFamily(link)));
                }
                Endpoint::UdpIn(_) | Endpoint::TcpIn(_) => {}
                other if g.link.is_some() => {
                    return Err((arg(), LinkOptionError::NotListening(other.to_string())))
                }
                _ => {}
            }
        }
    }
    Ok(())
}

/// Refuses a link of `flag` (`given`, at `indices`) that is no serial
/// port among `endpoints`.
pub fn check_serial(
    flag: &str,
    given: &[LinkRef],
    indices: &[usize],
    endpoints: &[fbwag_dialect::Endpoint],
) -> Result<(), (String, LinkOptionError)> {
    for (link, &i) in given.iter().zip(indices) {
        match endpoints.get(i) {
            Some(fbwag_dialect::Endpoint::Serial { .. }) | None => {}
            Some(other) => {
                return Err((
                    format!("{flag} {link}"),
                    LinkOptionError::NotSerial(other.to_string()),
                ))
            }
        }
    }
    Ok(())
}

/// The filters `--filter-in` (`ins`) and `--filter-out` (`outs`) rules
/// make, over links named `names`; an error names the flag and value at
/// fault.
pub fn link_filters(
    ins: &[LinkRule],
    outs: &[LinkRule],
    names: &[Option<String>],
) -> Result<Vec<LinkFilter>, (String, LinkOptionError)> {
    let mut filters: Vec<(usize, Direction, FilterRules, Vec<String>)> = Vec::new();
    let given = [(Direction::In, ins), (Direction::Out, outs)];
    for (direction, rules) in given {
        for r in rules {
            let flag = match direction {
                Direction::In => "--filter-in",
                Direction::Out => "--filter-out",
            };
            let fault = |e| (format!("{flag} {}:{}", r.link, r.rule), e);
            let index = r.link.index(names).map_err(fault)?;
            let at = match filters
                .iter()
                .position(|f| f.0 == index && f.1 == direction)
            {
                Some(at) => at,
                None => {
                    filters.push((index, direction, FilterRules::new(), Vec::new()));
                    filters.len() - 1
                }
            };
            let entry = &mut filters[at];
            entry.2.parse(&r.rule).map_err(|e| fault(e.into()))?;
            entry.3.push(r.rule.clone());
        }
    }
    Ok(filters
        .into_iter()
        .map(|(index, direction, rules, text)| LinkFilter {
            index,
            direction,
            filter: rules.filter(),
            rules: text,
        })
        .collect())
}

/// Refuses a `--filter-in` rule of the link of index `autonomy` (among
/// links named `names`) that blocks one of the control messages: filters
/// never touch them, so such a rule would only seem to keep the autonomy
/// from steering.
pub fn check_autonomy_rules(
    ins: &[LinkRule],
    autonomy: usize,
    names: &[Option<String>],
) -> Result<(), (String, LinkOptionError)> {
    for r in ins.iter().filter(|r| r.link.index(names) == Ok(autonomy)) {
        let mut rules = FilterRules::new();
        // Checked as it was read: an error here cannot block anything.
        if rules.parse(&r.rule).is_err() {
            continue;
        }
        let control = Control::MESSAGES
            .into_iter()
            .find(|(id, _)| rules.blocks_msg(*id));
        if let Some((_, name)) = control {
            let arg = format!("--filter-in {}:{}", r.link, r.rule);
            return Err((arg, LinkOptionError::AutonomyControl(name)));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unnamed(n: usize) -> Vec<Option<String>> {
        vec![None; n]
    }

    #[test]
    fn a_value_for_one_link_outranks_the_one_for_every_link() {
        let peers: Vec<_> = ["10.0.0.1:14550", "3:10.0.0.3:14550", "[::1]:5760"]
            .iter()
            .map(|s| link_peer(s).unwrap())
            .collect();
        assert_eq!(peers[0].link, None);
        assert_eq!(peers[1].link, Some(LinkRef::Place(3)));
        assert_eq!(peers[2].link, None, "an IPv6 address is no link");
        let each = per_link("--peer", &peers[..2], &unnamed(3)).unwrap();
        let addr = |s: &str| Some(s.parse::<SocketAddr>().unwrap());
        let every = addr("10.0.0.1:14550");
        assert_eq!(each, vec![every, every, addr("10.0.0.3:14550")]);
        let own = per_link("--peer", &peers[1..2], &unnamed(3)).unwrap();
        assert_eq!(own[0], None);
        let key = "ab".repeat(32);
        let place = link_sign_key(&format!("2:{key}")).unwrap().link;
        assert_eq!(place, Some(LinkRef::Place(2)));
        assert_eq!(link_sign_key(&key).unwrap().link, None);
        assert!(link_peer("2:nowhere").is_err());
    }

    #[test]
    fn a_later_value_for_a_link_wins_and_one_past_the_last_is_refused() {
        let peer = |s: &str| link_peer(s).unwrap();
        let addr = |s: &str| Some(s.parse::<SocketAddr>().unwrap());
        let twice = [peer("2:10.0.0.1:1"), peer("2:10.0.0.2:1")];
        let got = per_link("--peer", &twice, &unnamed(2)).unwrap();
        assert_eq!(got, vec![None, addr("10.0.0.2:1")]);
        let both = [peer("10.0.0.1:1"), peer("10.0.0.2:1")];
        let got = per_link("--peer", &both, &unnamed(2)).unwrap();
        assert_eq!(got, vec![addr("10.0.0.2:1"); 2]);
        let past = [peer("3:10.0.0.1:1")];
        let err = per_link("--peer", &past, &unnamed(2)).unwrap_err().1;
        assert_eq!(err, LinkOptionError::NoSuchLink { link: 3, links: 2 });
    }

    /// A peer pinned on a link that does not listen would be ignored
    /// while the log said otherwise; IP:0 on udpin would answer nobody.
    #[test]
    fn a_peer_goes_only_where_it_applies() {
        let peer = |s: &str| link_peer(s).unwrap();
        let links: Vec<fbwag_dialect::Endpoint> =
            ["udpin:0.0.0.0:1", "udpout:10.0.0.9:2", "tcpin:0.0.0.0:3"]
                .map(|e| e.parse().unwrap())
                .into();
        let names = unnamed(3);
        let ok = [peer("10.0.0.1:1"), peer("3:10.0.0.2:0")];
        assert!(check_peers(&ok, &links, &names).is_ok());
        let err = check_peers(&[peer("2:10.0.0.1:1")], &links, &names).unwrap_err();
        assert!(matches!(err.1, LinkOptionError::NotListening(_)), "{err:?}");
        let err = check_peers(&[peer("3:[::1]:5")], &links, &names).unwrap_err();
        assert!(matches!(err.1, LinkOptionError::OtherFamily(_)), "{err:?}");
        for any_port in ["10.0.0.1:0", "1:10.0.0.1:0"] {
            let err = check_peers(&[peer(any_port)], &links, &names).unwrap_err();
            assert_eq!(err.1, LinkOptionError::AnyPort, "{any_port}");
        }
    }

    #[test]
    fn a_link_is_named_by_its_place_or_by_its_name() {
        assert_eq!(link("3").ok(), Some(LinkRef::Place(3)));
        assert_eq!(link("gcs").ok(), Some(LinkRef::Name("gcs".into())));
        for bad in ["0", "x y", "1gcs", "udpin", "passphrase", &"a".repeat(33)] {
            assert!(link(bad).is_err(), "{bad:?}");
        }
        let names = link_names(
            "--out",
            [
                "fc=serial:/dev/ttyAMA0:921600",
                "udpin:0.0.0.0:1",
                "gcs=udpout:10.0.0.2:14550",
            ],
        )
        .unwrap();
        assert_eq!(names, [Some("fc".into()), None, Some("gcs".into())]);
        let refs = [LinkRef::Place(3), LinkRef::Name("fc".into())];
        assert_eq!(link_indices("--sniffer", &refs, &names), Ok(vec![2, 0]));
        let (arg, e) = link_indices("--sniffer", &[LinkRef::Place(4)], &names).unwrap_err();
        assert_eq!(arg, "--sniffer 4");
        assert_eq!(e, LinkOptionError::NoSuchLink { link: 4, links: 3 });
        let (arg, e) = link_indices("--sniffer", &[LinkRef::Name("x".into())], &names).unwrap_err();
        assert_eq!(arg, "--sniffer x");
        assert_eq!(e.to_string(), "no link is named x (names: fc, gcs)");
        let twice = link_names("--out", ["a=udpin:0.0.0.0:1", "a=udpin:0.0.0.0:2"]);
        assert!(matches!(twice, Err((_, LinkOptionError::NameTwice(_)))));
        // A connection string, a key file, a passphrase: no name.
        assert_eq!(
            split_link_name("udpin:0.0.0.0:1"),
            (None, "udpin:0.0.0.0:1")
        );
        assert_eq!(
            split_link_name(" gcs = udpin:0.0.0.0:1"),
            (Some("gcs"), "udpin:0.0.0.0:1")
        );
        let named = link_sign_key(&format!("gcs:{}", "ab".repeat(32))).unwrap();
        assert_eq!(named.link, Some(LinkRef::Name("gcs".into())));
        let rule = link_rule("gcs:block-msg=COMMAND_LONG").unwrap();
        assert_eq!(rule.link, LinkRef::Name("gcs".into()));
    }
}

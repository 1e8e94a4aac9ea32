//! SETUP_SIGNING as ArduPilot handles it: refused while armed; otherwise
//! the key signs and verifies on every link at once, and only signed
//! frames count from then on (a key of zeros with a zero timestamp turns
//! signing off). With `--signing-state PATH` the key is kept in `PATH.key`
//! (mode 600, as `fbwag key new` writes one) and taken again at start, as
//! ArduPilot keeps it in its storage.

use super::Daemon;
use crate::live::net::Net;
use fbwag_delegation::fc::FcConfig;
use fbwag_delegation::{Moment, Peer};
use serde_json::json;
use std::io::{self, Write};
use std::path::{Path, PathBuf};

/// Where the key of `--signing-state PATH` is kept.
pub fn key_file(state: &Path) -> PathBuf {
    let mut name = state.as_os_str().to_owned();
    name.push(".key");
    PathBuf::from(name)
}

/// The key kept at `path`, if there is one.
pub fn load(path: &Path) -> io::Result<Option<[u8; 32]>> {
    let text = match std::fs::read_to_string(path) {
        Ok(text) => text,
        Err(e) if e.kind() == io::ErrorKind::NotFound => return Ok(None),
        Err(e) => return Err(e),
    };
    let bad = || {
        io::Error::new(
            io::ErrorKind::InvalidData,
            format!("{}: not 64 hex digits", path.display()),
        )
    };
    let hex = text.trim();
    if hex.len() != 64 {
        return Err(bad());
    }
    let mut key = [0u8; 32];
    for (i, byte) in key.iter_mut().enumerate() {
        *byte = u8::from_str_radix(hex.get(2 * i..2 * i + 2).ok_or_else(bad)?, 16)
            .map_err(|_| bad())?;
    }
    Ok(Some(key))
}

/// Keeps `key` at `path` (written whole, mode 600), or removes the file
/// when signing is off.
fn save(path: &Path, key: Option<[u8; 32]>) -> io::Result<()> {
    let Some(key) = key else {
        return match std::fs::remove_file(path) {
            Err(e) if e.kind() != io::ErrorKind::NotFound => Err(e),
            _ => Ok(()),
        };
    };
    let hex: String = key.iter().map(|b| format!("{b:02x}")).collect();
    let mut part = path.as_os_str().to_owned();
    part.push(".new");
    let part = PathBuf::from(part);
    let mut options = std::fs::OpenOptions::new();
    options.write(true).create(true).truncate(true);
    #[cfg(unix)]
    std::os::unix::fs::OpenOptionsExt::mode(&mut options, 0o600);
    let mut file = options.open(&part)?;
    file.write_all(format!("{hex}\n").as_bytes())?;
    file.sync_all()?;
    std::fs::rename(&part, path)
}

impl Daemon {
    /// SETUP_SIGNING from `from`: the key (`None`: signing off) on every
    /// link from now on, only signed frames counting while there is one;
    /// refused while armed.
    pub(super) fn setup_signing(
        &mut self,
        now: Moment,
        key: [u8; 32],
        timestamp: u64,
        from: Peer,
        net: &mut Net<'_, '_>,
    ) {
        if self.armed {
            let why = "signing: not while armed";
            return self.refusal(why, "SETUP_SIGNING", from, net);
        }
        let key = (key != [0; 32] || timestamp != 0).then_some(key);
        for link in net.out.links().iter() {
            net.out.set_key(link, key);
        }
        let fc = FcConfig {
            require_signed: key.is_some(),
            ..self.settings.fc
        };
        if self.node.reconfigure(fc, now).is_ok() {
            self.node.set_receiver_ok(self.receiver_ok || !self.armed);
            self.settings.fc = fc;
        }
        if let Some(path) = &self.key_file {
            if let Err(e) = save(path, key) {
                net.log.error(&format!(
                    "signing: cannot keep the key in {}: {e}",
                    path.display()
                ));
            }
        }
        let state = if key.is_some() { "on" } else { "off" };
        net.log.notice(&format!(
            "signing: {state} (SETUP_SIGNING from {}/{}){}",
            from.sysid,
            from.compid,
            if key.is_some() {
                ": signed frames only, on every link"
            } else {
                ""
            }
        ));
        self.events.emit(
            "signing",
            json!({"state": state, "sysid": from.sysid, "compid": from.compid}),
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_key_is_kept_readable_by_its_owner_only_and_read_back() {
        let dir = std::env::temp_dir().join(format!("fbwag-fc-key-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = key_file(&dir.join("fc.state"));
        assert_eq!(path.file_name().unwrap(), "fc.state.key");
        assert_eq!(load(&path).unwrap(), None);
        save(&path, Some([0xab; 32])).unwrap();
        assert_eq!(load(&path).unwrap(), Some([0xab; 32]));
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            let mode = std::fs::metadata(&path).unwrap().permissions().mode();
            assert_eq!(mode & 0o777, 0o600);
        }
        save(&path, None).unwrap();
        assert_eq!(load(&path).unwrap(), None);
        std::fs::write(&path, "zz").unwrap();
        assert!(load(&path).is_err());
        let _ = std::fs::remove_dir_all(&dir);
    }
}

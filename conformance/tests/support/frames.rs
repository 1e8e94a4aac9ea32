//! Frames built and parsed by the Rust side (mavframe), generic over the
//! dialect under test.

use super::values::values_text;
use mavframe::crc::frame_crc;
use mavframe::frame::{finish, Header, Version, HEADER_LEN_V1, HEADER_LEN_V2};
use mavframe::{BufferTooSmall, MessageMeta, MessageSet, Parser, Signer, Unsigned, Verifier};

/// The signing key of every signed frame of the tests (32 bytes 0x00..0x1f
/// reversed, so it is neither zero nor a simple pattern of the seed).
pub const KEY: [u8; 32] = {
    let mut k = [0u8; 32];
    let mut i = 0;
    while i < 32 {
        k[i] = 0x9e ^ (i as u8).wrapping_mul(37);
        i += 1;
    }
    k
};

/// A second key: frames signed with it carry bad signatures.
pub const OTHER_KEY: [u8; 32] = [0x5a; 32];

/// Frame kinds compared.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Mode {
    /// MAVLink 2, unsigned.
    V2,
    /// MAVLink 2, signed.
    V2s,
    /// MAVLink 1 (ids <= 255).
    V1,
}

impl Mode {
    pub const ALL: [Mode; 3] = [Mode::V2, Mode::V2s, Mode::V1];

    pub fn token(self) -> &'static str {
        match self {
            Mode::V2 => "v2",
            Mode::V2s => "v2s",
            Mode::V1 => "v1",
        }
    }

    pub fn label(self) -> &'static str {
        match self {
            Mode::V2 => "MAVLink 2",
            Mode::V2s => "MAVLink 2 signed",
            Mode::V1 => "MAVLink 1",
        }
    }

    pub fn version(self) -> Version {
        match self {
            Mode::V1 => Version::V1,
            _ => Version::V2,
        }
    }
}

/// The owned message enum of a generated dialect, made generic: every
/// generated `Message` enum has these as inherent methods.
pub trait Owned {
    fn emit_into(&self, payload: &mut [u8]) -> Result<usize, BufferTooSmall>;
    fn row(&self) -> &'static MessageMeta;
}

macro_rules! owned {
    ($t:ty) => {
        impl Owned for $t {
            fn emit_into(&self, payload: &mut [u8]) -> Result<usize, BufferTooSmall> {
                self.emit(payload)
            }
            fn row(&self) -> &'static MessageMeta {
                self.meta()
            }
        }
    };
}
owned!(fbwag_dialect::Message);
owned!(conformance::all_xml::all::Message);

/// Frames `payload` (any length up to `max_len`) with mavframe's `finish`.
pub fn build_frame(
    meta: &MessageMeta,
    mode: Mode,
    header: Header,
    payload: &[u8],
    link: u8,
    ts: u64,
    key: &[u8; 32],
) -> Vec<u8> {
    let mut out = [0u8; 300];
    let start = match mode {
        Mode::V1 => HEADER_LEN_V1,
        _ => HEADER_LEN_V2,
    };
    out[start..start + payload.len()].copy_from_slice(payload);
    let mut signer = (mode == Mode::V2s).then(|| Signer::new(*key, link, ts));
    let n = finish(
        mode.version(),
        header,
        meta,
        payload.len(),
        signer.as_mut(),
        &mut out,
    )
    .expect("frame fits");
    out[..n].to_vec()
}

/// A MAVLink 1 frame carrying the whole payload, extensions included: what
/// pymavlink's `force_mavlink1=True` sends (the C library and mavframe send
/// the base fields only).
pub fn v1_with_extensions(meta: &MessageMeta, header: Header, payload: &[u8]) -> Vec<u8> {
    let len = meta.max_len as usize;
    let mut f = vec![
        0xFE,
        len as u8,
        header.seq,
        header.sysid,
        header.compid,
        meta.id as u8,
    ];
    f.extend_from_slice(&payload[..len]);
    let crc = frame_crc(&f[1..], meta.crc_extra);
    f.extend_from_slice(&crc.to_le_bytes());
    f
}

/// What the Rust parser made of one whole frame.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RustDecode {
    /// `ok:SIG:SEQ:SYSID:COMPID:VALUES` or `rej:REASON` (the token the
    /// Python and C sides print).
    pub token: String,
    /// The frame encoded again from the owned message (typed `emit`, then
    /// `finish` with the frame's header and signature parameters).
    pub reencoded: Option<Vec<u8>>,
}

/// Parses `frame` with a fresh `Parser<D>` (verifying signatures with
/// [`KEY`], unsigned refused, when `signed`), reads its values through the
/// field table, checks the typed owned message gives the same payload, and
/// re-encodes it.
pub fn rust_decode<D: MessageSet>(frame: &[u8], signed: bool) -> RustDecode
where
    D::Message: Owned,
{
    let mut parser = if signed {
        Parser::<D>::with_signing(Verifier::new(KEY), Unsigned::Refuse)
    } else {
        Parser::<D>::new()
    };
    let rej = |why: &str| RustDecode {
        token: format!("rej:{why}"),
        reencoded: None,
    };
    let mut input = frame;
    let mut result = None;
    let mut count = 0;
    while let Some(rx) = parser.next(&mut input) {
        count += 1;
        result = Some(one(&rx));
    }
    while let Some(rx) = parser.flush() {
        count += 1;
        result = Some(one(&rx));
    }
    match (count, result) {
        (1, Some(r)) => r,
        (n, _) => rej(&format!("frames={n}")),
    }
}

fn one<D: MessageSet>(rx: &mavframe::Received<'_, D>) -> RustDecode
where
    D::Message: Owned,
{
    let Some(meta) = rx.meta() else {
        return RustDecode {
            token: "rej:unknown-id".into(),
            reencoded: None,
        };
    };
    let f = rx.frame();
    let h = f.header();
    let generic = values_text(meta, f.payload());
    // The typed path: owned message (through the view accessors) → emit.
    let msg = rx.message().expect("known id");
    let mut full = [0u8; 256];
    let n = msg.emit_into(&mut full).expect("payload fits");
    assert_eq!(msg.row().id, meta.id);
    let typed = values_text(meta, &full[..n]);
    if typed != generic {
        return RustDecode {
            token: format!("rej:typed-path-differs:{typed}"),
            reencoded: None,
        };
    }
    let (link, ts) = f
        .signature()
        .map_or((0, 0), |s| (s.link_id(), s.timestamp()));
    let mode = match (f.version(), f.is_signed()) {
        (Version::V1, _) => Mode::V1,
        (_, true) => Mode::V2s,
        _ => Mode::V2,
    };
    let reencoded = build_frame(meta, mode, h, &full[..n], link, ts, &KEY);
    RustDecode {
        token: format!(
            "ok:{}:{}:{}:{}:{generic}",
            u8::from(rx.is_authenticated()),
            h.seq,
            h.sysid,
            h.compid
        ),
        reencoded: Some(reencoded),
    }
}

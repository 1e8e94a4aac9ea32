//! The same receiver on the `mavlink` crate's `embedded` build: a stream of
//! bytes in, the `custom_mode` of the last HEARTBEAT out.
#![no_std]

use mavlink::dialects::minimal::MavMessage;
use mavlink::error::MessageReadError;
use mavlink::MavlinkReader;

/// The `custom_mode` of the last HEARTBEAT in the `len` bytes at `data`
/// (`u32::MAX` when there is none).
///
/// # Safety
///
/// `data` points to `len` readable bytes.
#[no_mangle]
pub unsafe extern "C" fn receive(data: *const u8, len: usize) -> u32 {
    // SAFETY: the caller's promise above.
    let input = unsafe { core::slice::from_raw_parts(data, len) };
    let mut reader = MavlinkReader::new(input);
    let mut mode = u32::MAX;
    // Until the input ends (a read fails); a frame the reader cannot
    // parse is passed over.
    loop {
        match reader.read_any_message::<MavMessage>() {
            Ok((_, MavMessage::HEARTBEAT(h))) => mode = h.custom_mode,
            Err(MessageReadError::Parse(_)) => {}
            Err(_) => return mode,
        }
    }
}

#[panic_handler]
fn panic(_: &core::panic::PanicInfo) -> ! {
    loop {}
}

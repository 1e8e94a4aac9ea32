//! A `no_std` receiver on mavframe: a stream of bytes in, the `custom_mode`
//! of the last HEARTBEAT out. Resynchronisation after garbage and the
//! parser's bound on work per byte are those of every mavframe build.
#![no_std]

mod dialect {
    include!(concat!(env!("OUT_DIR"), "/mod.rs"));
}

use dialect::minimal::{Dialect, MessageView};
use mavframe::Parser;

/// The `custom_mode` of the last HEARTBEAT in the `len` bytes at `data`
/// (`u32::MAX` when there is none).
///
/// # Safety
///
/// `data` points to `len` readable bytes.
#[no_mangle]
pub unsafe extern "C" fn receive(data: *const u8, len: usize) -> u32 {
    // SAFETY: the caller's promise above.
    let mut input = unsafe { core::slice::from_raw_parts(data, len) };
    let mut parser = Parser::<Dialect>::new();
    let mut mode = u32::MAX;
    // The stream, then its end: a frame of an unknown id that waited for
    // the byte after it is decided there.
    while let Some(rx) = parser.next(&mut input) {
        if let Some(MessageView::Heartbeat(h)) = rx.view() {
            mode = h.custom_mode();
        }
    }
    while let Some(rx) = parser.flush() {
        if let Some(MessageView::Heartbeat(h)) = rx.view() {
            mode = h.custom_mode();
        }
    }
    mode
}

#[panic_handler]
fn panic(_: &core::panic::PanicInfo) -> ! {
    loop {}
}

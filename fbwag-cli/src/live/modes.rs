//! ArduPlane's flight mode names.

/// The ArduPlane name of a HEARTBEAT `custom_mode` (FBWAG: this protocol's
/// companion-control mode).
pub fn mode_name(custom_mode: u32) -> String {
    use fbwag_delegation::mode;
    match custom_mode {
        mode::MANUAL => "MANUAL".into(),
        mode::CIRCLE => "CIRCLE".into(),
        mode::FBWA => "FBWA".into(),
        mode::RTL => "RTL".into(),
        mode::GUIDED => "GUIDED".into(),
        mode::FBWAG => "FBWAG".into(),
        other => format!("MODE({other})"),
    }
}

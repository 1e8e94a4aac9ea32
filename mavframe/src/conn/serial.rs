//! Serial ports (feature `serial`), through the `serialport` crate.

use super::transport::{recv_stream, Transport};
use std::boxed::Box;
use std::io::{self, Read, Write};
use std::time::Duration;

/// How long a write may wait for the device to take the bytes (a UART at
/// 9600 baud sends a full-size frame in about 0.3 s).
pub const WRITE_TIMEOUT: Duration = Duration::from_secs(2);

/// The longest single wait handed to the serial port: waits without a
/// limit are made of these, so no platform's timeout type can overflow.
const LONG_WAIT: Duration = Duration::from_secs(3600);

/// `serial:`: a serial device at a fixed baud rate, 8N1, no flow control
/// (the `serialport` defaults, which flight controllers use).
pub struct Serial {
    port: Box<dyn serialport::SerialPort>,
}

impl core::fmt::Debug for Serial {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Serial")
            .field("name", &self.port.name())
            .field("baud", &self.port.baud_rate().ok())
            .finish()
    }
}

impl Serial {
    /// Opens the device at `path` with `baud`.
    pub fn open(path: &str, baud: u32) -> io::Result<Self> {
        let port = serialport::new(path, baud).open()?;
        Ok(Serial { port })
    }

    /// Wraps a port opened by other means (a pseudo-terminal, other
    /// settings).
    pub fn from_port(port: Box<dyn serialport::SerialPort>) -> Self {
        Serial { port }
    }

    /// The port, for settings this type does not cover.
    pub fn port_mut(&mut self) -> &mut dyn serialport::SerialPort {
        &mut *self.port
    }
}

impl Serial {
    /// The send half: another handle on the same device (serialport's
    /// `try_clone`; each handle keeps its own timeout).
    pub(crate) fn split_sender(&mut self) -> io::Result<Serial> {
        Ok(Serial {
            port: self.port.try_clone()?,
        })
    }
}

impl Transport for Serial {
    fn send(&mut self, frame: &[u8]) -> io::Result<()> {
        // One timeout serves reads and writes in serialport: a zero read
        // timeout left from recv would fail any write that has to wait.
        self.port.set_timeout(WRITE_TIMEOUT)?;
        self.port.write_all(frame)
    }

    fn recv(&mut self, buf: &mut [u8], timeout: Option<Duration>) -> io::Result<usize> {
        let port = &mut self.port;
        recv_stream(buf, timeout, "serial device closed", |buf, wait| {
            port.set_timeout(wait.unwrap_or(LONG_WAIT).min(LONG_WAIT))?;
            port.read(buf)
        })
    }
}

#[cfg(all(test, unix))]
mod tests {
    use super::*;
    use serialport::TTYPort;

    /// A real serial round trip over a pseudo-terminal pair.
    #[test]
    fn pty_pair_round_trip() {
        let (a, b) = match TTYPort::pair() {
            Ok(pair) => pair,
            // No /dev/ptmx in this sandbox: nothing to test against.
            Err(e) => {
                std::eprintln!("skipped: no pseudo-terminal ({e})");
                return;
            }
        };
        let mut a = Serial::from_port(Box::new(a));
        let mut b = Serial::from_port(Box::new(b));
        let mut buf = [0u8; 64];
        // Nothing sent yet: a bounded wait reads nothing.
        assert_eq!(
            b.recv(&mut buf, Some(Duration::from_millis(50))).unwrap(),
            0
        );
        assert_eq!(b.recv(&mut buf, Some(Duration::ZERO)).unwrap(), 0);
        a.send(b"\xfd\x01hello").unwrap();
        let mut got = std::vec::Vec::new();
        while got.len() < 7 {
            let n = b.recv(&mut buf, Some(Duration::from_secs(2))).unwrap();
            assert!(n > 0, "timed out after {got:?}");
            got.extend_from_slice(&buf[..n]);
        }
        assert_eq!(got, b"\xfd\x01hello");
        b.send(b"back").unwrap();
        let n = a.recv(&mut buf, Some(Duration::from_secs(2))).unwrap();
        assert_eq!(&buf[..n], b"back");
    }
}

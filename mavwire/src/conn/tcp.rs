//! TCP transports: `tcp` (client) and `tcpin` (server for many clients).

use super::transport::{is_timeout, Deadline, ReadMode, SetReadMode, Transport};
use crate::frame::{frame_len, FrameError};
use core::fmt;
use std::collections::VecDeque;
use std::io::{self, Read, Write};
use std::net::{Shutdown, SocketAddr, TcpListener, TcpStream};
use std::sync::{Arc, Condvar, Mutex, MutexGuard, PoisonError};
use std::thread;
use std::time::{Duration, Instant};
use std::vec;
use std::vec::Vec;

/// A connection closed by its peer: an error, so that 0 from
/// [`Transport::recv`] keeps meaning "timed out".
fn closed() -> io::Error {
    io::Error::new(io::ErrorKind::UnexpectedEof, "connection closed by peer")
}

/// `tcp:`: a TCP client.
///
/// Nagle's algorithm is off (`TCP_NODELAY`): frames are small and
/// latency-sensitive. A closed connection is an `UnexpectedEof` error from
/// [`recv`](Transport::recv); reconnecting is the caller's choice (open the
/// endpoint again).
#[derive(Debug)]
pub struct TcpClient {
    stream: TcpStream,
    mode: ReadMode,
}

impl TcpClient {
    /// Connects to `addr`, waiting as long as the system does.
    pub fn connect(addr: SocketAddr) -> io::Result<Self> {
        Self::from_stream(TcpStream::connect(addr)?)
    }

    /// Connects to `addr`, giving up after `timeout`.
    pub fn connect_timeout(addr: SocketAddr, timeout: Duration) -> io::Result<Self> {
        Self::from_stream(TcpStream::connect_timeout(&addr, timeout)?)
    }

    /// Wraps a connected stream (sets `TCP_NODELAY`).
    pub fn from_stream(stream: TcpStream) -> io::Result<Self> {
        stream.set_nodelay(true)?;
        Ok(TcpClient {
            stream,
            mode: ReadMode::default(),
        })
    }

    /// The local address.
    pub fn local_addr(&self) -> io::Result<SocketAddr> {
        self.stream.local_addr()
    }

    /// The server's address.
    pub fn peer_addr(&self) -> io::Result<SocketAddr> {
        self.stream.peer_addr()
    }

    /// The stream, for options this type does not cover (a write timeout,
    /// for one: writes block until the peer takes the bytes).
    pub fn get_ref(&self) -> &TcpStream {
        &self.stream
    }
}

impl Transport for TcpClient {
    fn send(&mut self, frame: &[u8]) -> io::Result<()> {
        // A zero-timeout recv leaves the socket non-blocking, and a write
        // cut short by WouldBlock would leave half a frame on the stream.
        self.stream.ensure_nonblocking(&mut self.mode, false)?;
        self.stream.write_all(frame)
    }

    fn recv(&mut self, buf: &mut [u8], timeout: Option<Duration>) -> io::Result<usize> {
        if buf.is_empty() {
            return Ok(0);
        }
        let deadline = Deadline::after(timeout);
        loop {
            self.stream
                .prepare_read(&mut self.mode, deadline.remaining())?;
            match self.stream.read(buf) {
                Ok(0) => return Err(closed()),
                Ok(n) => return Ok(n),
                Err(e) if is_timeout(&e) => return Ok(0),
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {
                    if deadline.passed() {
                        return Ok(0);
                    }
                }
                Err(e) => return Err(e),
            }
        }
    }
}

/// Output a slow client may have pending before it is dropped: 64 KiB,
/// about 240 full-size frames. Blocking on one stalled client would stall
/// every other client, and cutting a frame short would corrupt its stream.
pub const MAX_PENDING_OUTPUT: usize = 64 * 1024;

/// How long [`TcpServer::recv`](Transport::recv) waits for its clients'
/// bytes before it looks for new connections again: std cannot wait on a
/// listener and anything else at once, and accepting stays on the caller's
/// thread (see [`TcpServer`]). This bounds how late a client that connects
/// during a wait is served, and sets the wake-up rate of an idle wait
/// (20 per second).
const ACCEPT_POLL: Duration = Duration::from_millis(50);

/// Bytes a reader thread asks its socket for at a time.
const READ_LEN: usize = 16 * 1024;

/// Chunks a reader thread may have waiting for `recv`; then it stops
/// reading, and TCP flow control slows its client down.
const READ_QUEUE: usize = 8;

/// How long a writer thread's write may block before it checks whether its
/// client was given up (the socket's write timeout).
const WRITE_CHECK: Duration = Duration::from_secs(1);

/// How long `send` waits for a client's writer thread to hand its output to
/// the socket before the client counts as too slow. Output still queued may
/// only mean that the thread has not run yet (a burst of sends, a busy
/// machine): the cap is meant for bytes the socket will not take.
const CATCH_UP: Duration = Duration::from_millis(20);

/// Locks, ignoring poisoning: no code here panics with a lock held, and the
/// data stays consistent at every unlock anyway.
fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

/// Waits on `cv` up to `timeout`.
fn wait<'a, T>(cv: &Condvar, guard: MutexGuard<'a, T>, timeout: Duration) -> MutexGuard<'a, T> {
    match cv.wait_timeout(guard, timeout) {
        Ok((guard, _)) => guard,
        Err(poisoned) => poisoned.into_inner().0,
    }
}

/// How a client's writer goes on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Writing {
    /// Serving the client.
    Open,
    /// The server was dropped: write what is queued, then end (giving up
    /// on a write blocked for [`WRITE_CHECK`]).
    Finish,
    /// The client was dropped: end now, discarding what is queued.
    Discard,
    /// A write failed; the writer has ended.
    Failed,
}

/// The output side of a client, shared with its writer thread.
#[derive(Debug)]
struct Outbox {
    /// Bytes `send` queued that the writer has not taken yet.
    queued: Vec<u8>,
    /// Bytes the writer took and has not finished writing.
    writing: usize,
    state: Writing,
    /// The writer waits on `ready` / a `send` waits on `progress`:
    /// signals are sent only to a waiting thread.
    writer_idle: bool,
    sender_waiting: bool,
}

/// The input side of a client, shared with its reader thread.
#[derive(Debug)]
struct Inbox {
    /// Chunks of whole frames (see [`whole_frames`]), oldest first.
    chunks: VecDeque<Vec<u8>>,
    /// The reader ended (the client closed or failed): no more chunks.
    ended: bool,
    /// The server gave the client up or was dropped: the reader stops.
    closed: bool,
    /// The reader waits on `room` for the queue to shrink.
    reader_waiting: bool,
}

/// What a client's threads and the server share.
#[derive(Debug)]
struct Shared {
    outbox: Mutex<Outbox>,
    /// The writer: output queued, or a state change.
    ready: Condvar,
    /// A `send`: the writer took or wrote output, or ended.
    progress: Condvar,
    inbox: Mutex<Inbox>,
    /// The reader: a chunk was taken, or the client closed.
    room: Condvar,
}

/// The server's wake-up: raised by a reader when it queued a chunk or
/// ended, awaited by `recv`.
#[derive(Debug, Default)]
struct Signal {
    /// (raised, `recv` waiting)
    state: Mutex<(bool, bool)>,
    cv: Condvar,
}

impl Signal {
    fn raise(&self) {
        let mut s = lock(&self.state);
        s.0 = true;
        if s.1 {
            self.cv.notify_one();
        }
    }

    fn clear(&self) {
        lock(&self.state).0 = false;
    }

    /// Waits up to `timeout` for a raise since the last `clear`.
    fn wait(&self, timeout: Duration) {
        let mut s = lock(&self.state);
        if !s.0 {
            s.1 = true;
            s = wait(&self.cv, s, timeout);
            s.1 = false;
        }
    }
}

/// A thread of a client, started through one closure type (each closure
/// type given to `thread::spawn` is compiled separately).
enum Job {
    Read(TcpStream, Arc<Shared>, Arc<Signal>),
    Write(TcpStream, Arc<Shared>),
}

fn spawn(job: Job, token: &Arc<()>) -> io::Result<()> {
    let name = match job {
        Job::Read(..) => "tcpin-read",
        Job::Write(..) => "tcpin-write",
    };
    let token = Arc::clone(token);
    thread::Builder::new().name(name.into()).spawn(move || {
        match job {
            Job::Read(stream, shared, signal) => read_loop(stream, &shared, &signal),
            Job::Write(stream, shared) => write_loop(stream, &shared),
        }
        drop(token);
    })?;
    Ok(())
}

struct Client {
    /// For `shutdown`, which wakes the client's threads; they hold clones.
    stream: TcpStream,
    addr: SocketAddr,
    shared: Arc<Shared>,
    /// The chunk `recv` is returning, and how far.
    chunk: Vec<u8>,
    at: usize,
    /// Bytes left of a frame a small `recv` buffer cut.
    cut_left: usize,
    /// Closed, failed or too slow: removed at the next clean-up.
    dead: bool,
}

impl Client {
    /// Starts the reader and writer threads of a client just accepted.
    fn start(
        stream: TcpStream,
        addr: SocketAddr,
        signal: &Arc<Signal>,
        token: &Arc<()>,
    ) -> io::Result<Client> {
        // BSDs hand out accepted sockets non-blocking like the listener;
        // the threads need blocking ones.
        stream.set_nonblocking(false)?;
        // Small frames, latency-sensitive; a failure here is harmless.
        let _ = stream.set_nodelay(true);
        stream.set_write_timeout(Some(WRITE_CHECK))?;
        let shared = Arc::new(Shared {
            outbox: Mutex::new(Outbox {
                queued: Vec::new(),
                writing: 0,
                state: Writing::Open,
                writer_idle: false,
                sender_waiting: false,
            }),
            ready: Condvar::new(),
            progress: Condvar::new(),
            inbox: Mutex::new(Inbox {
                chunks: VecDeque::new(),
                ended: false,
                closed: false,
                reader_waiting: false,
            }),
            room: Condvar::new(),
        });
        let client = Client {
            stream,
            addr,
            shared,
            chunk: Vec::new(),
            at: 0,
            cut_left: 0,
            dead: false,
        };
        let reader = Job::Read(
            client.stream.try_clone()?,
            Arc::clone(&client.shared),
            Arc::clone(signal),
        );
        let writer = Job::Write(client.stream.try_clone()?, Arc::clone(&client.shared));
        spawn(reader, token)?;
        if let Err(e) = spawn(writer, token) {
            client.close(Writing::Discard, Shutdown::Both); // ends the reader
            return Err(e);
        }
        Ok(client)
    }

    /// Queues `frame` for the writer thread; false when the client must be
    /// dropped: more than [`MAX_PENDING_OUTPUT`] behind even after waiting
    /// [`CATCH_UP`] for the writer (a larger frame passes when nothing is
    /// pending, as the kernel would take it), or the writer failed.
    fn send(&mut self, frame: &[u8]) -> bool {
        let shared = &*self.shared;
        let mut out = lock(&shared.outbox);
        let mut deadline = None;
        loop {
            if out.state != Writing::Open {
                return false;
            }
            let pending = out.queued.len() + out.writing;
            if pending == 0 || pending + frame.len() <= MAX_PENDING_OUTPUT {
                break;
            }
            let deadline = *deadline.get_or_insert_with(|| Instant::now() + CATCH_UP);
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return false;
            }
            out.sender_waiting = true;
            out = wait(&shared.progress, out, left);
            out.sender_waiting = false;
        }
        out.queued.extend_from_slice(frame);
        if out.writer_idle {
            shared.ready.notify_one();
        }
        true
    }

    /// Copies the client's next bytes into `buf`, whole frames only unless
    /// `buf` cannot hold one; `None` when none are waiting (or the reader
    /// ended: the client is then dead). The flag is false when a frame is
    /// cut, so that `recv` stays with this client until it is whole.
    fn take(&mut self, buf: &mut [u8]) -> Option<(usize, bool)> {
        if self.at == self.chunk.len() {
            if self.dead {
                return None;
            }
            let mut inbox = lock(&self.shared.inbox);
            match inbox.chunks.pop_front() {
                Some(chunk) => {
                    self.chunk = chunk;
                    self.at = 0;
                    if inbox.reader_waiting {
                        self.shared.room.notify_one();
                    }
                }
                None => {
                    self.dead = inbox.ended;
                    return None;
                }
            }
        }
        // A chunk ends at a frame boundary: the reader cut it there.
        let rest = &self.chunk[self.at..];
        let n = if self.cut_left > 0 {
            // The rest of a frame cut by the last call (the chunk holds it).
            let n = self.cut_left.min(buf.len()).min(rest.len());
            self.cut_left -= n;
            n
        } else if rest.len() <= buf.len() {
            rest.len()
        } else {
            match whole_frames(&rest[..buf.len()]) {
                0 => {
                    // A frame longer than `buf` starts here: cut it.
                    let frame = frame_len(rest).map_or(rest.len(), |n| n.min(rest.len()));
                    self.cut_left = frame.saturating_sub(buf.len());
                    buf.len()
                }
                n => n,
            }
        };
        buf[..n].copy_from_slice(&rest[..n]);
        self.at += n;
        if self.at == self.chunk.len() {
            self.cut_left = 0; // cannot be left: the chunk held the frame
        }
        Some((n, self.cut_left == 0))
    }

    /// Tells both threads to end (the writer as `writing` says), and wakes
    /// them: from their condition variables, and from a blocked read or
    /// write by shutting the socket down (`how`).
    fn close(&self, writing: Writing, how: Shutdown) {
        let shared = &*self.shared;
        {
            let mut out = lock(&shared.outbox);
            if out.state == Writing::Open {
                out.state = writing;
            }
            shared.ready.notify_one();
            shared.progress.notify_all();
        }
        lock(&shared.inbox).closed = true;
        shared.room.notify_one();
        let _ = self.stream.shutdown(how);
    }
}

/// A client's reader thread: reads until the client closes or fails, or
/// the server gives it up, and queues the bytes cut at frame boundaries
/// (the start of a frame whose end has not arrived waits for the rest),
/// raising the server's signal after each chunk and at the end.
fn read_loop(mut stream: TcpStream, shared: &Shared, signal: &Signal) {
    let mut buf = vec![0u8; READ_LEN];
    let mut held = 0;
    loop {
        let n = match stream.read(&mut buf[held..]) {
            Ok(0) => break,
            Ok(n) => n,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
            Err(_) => break,
        };
        let total = held + n;
        let mut cut = whole_frames(&buf[..total]);
        if cut == 0 && total == buf.len() {
            // Unreachable (what is held is less than one frame, and the
            // buffer holds many), but never stop reading for it.
            cut = total;
        }
        if cut > 0 {
            let mut inbox = lock(&shared.inbox);
            while inbox.chunks.len() >= READ_QUEUE && !inbox.closed {
                inbox.reader_waiting = true;
                inbox = match shared.room.wait(inbox) {
                    Ok(guard) => guard,
                    Err(poisoned) => poisoned.into_inner(),
                };
                inbox.reader_waiting = false;
            }
            if inbox.closed {
                return;
            }
            inbox.chunks.push_back(buf[..cut].to_vec());
            drop(inbox);
            signal.raise();
        }
        buf.copy_within(cut..total, 0);
        held = total - cut;
    }
    lock(&shared.inbox).ended = true;
    signal.raise();
}

/// A client's writer thread: writes what `send` queued, in order, until
/// the client is dropped, or the server is (after writing what was queued),
/// or a write fails. At the end it shuts the socket down, which ends the
/// reader too.
fn write_loop(mut stream: TcpStream, shared: &Shared) {
    let mut batch = Vec::new();
    loop {
        {
            let mut out = lock(&shared.outbox);
            loop {
                match out.state {
                    Writing::Open | Writing::Finish if !out.queued.is_empty() => break,
                    Writing::Open => {}
                    Writing::Finish | Writing::Discard | Writing::Failed => {
                        drop(out);
                        let _ = stream.shutdown(Shutdown::Both);
                        return;
                    }
                }
                out.writer_idle = true;
                out = match shared.ready.wait(out) {
                    Ok(guard) => guard,
                    Err(poisoned) => poisoned.into_inner(),
                };
                out.writer_idle = false;
            }
            // Take the whole queue; `send` refills the other buffer.
            core::mem::swap(&mut out.queued, &mut batch);
            out.writing = batch.len();
        }
        let result = write_all(&mut stream, &batch, shared);
        let mut out = lock(&shared.outbox);
        out.writing = 0;
        if result.is_err() {
            out.state = Writing::Failed;
        }
        if out.sender_waiting {
            shared.progress.notify_all();
        }
        batch.clear();
    }
}

/// `write_all` on a socket with a write timeout: a timed-out write is
/// retried while the client is served.
fn write_all(stream: &mut TcpStream, mut data: &[u8], shared: &Shared) -> io::Result<()> {
    while !data.is_empty() {
        match stream.write(data) {
            Ok(0) => return Err(io::ErrorKind::WriteZero.into()),
            Ok(n) => data = &data[n..],
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(e) if is_timeout(&e) => {
                if lock(&shared.outbox).state != Writing::Open {
                    return Err(e);
                }
            }
            Err(e) => return Err(e),
        }
    }
    Ok(())
}

/// `tcpin:`: a TCP server: accepts clients, sends every frame to all of
/// them, receives from any.
///
/// New clients are accepted on the caller's thread, without blocking,
/// inside [`send`](Transport::send), [`recv`](Transport::recv) and
/// [`accept_pending`](Self::accept_pending): a client whose `connect` has
/// returned gets the next frame sent. Each client then has two threads of
/// its own (std cannot wait on several sockets at once): a reader, which
/// passes the client's bytes to `recv`, and a writer, which writes what
/// `send` queued, so that `send` does not wait for the network. A client
/// that closes or fails, or falls more than [`MAX_PENDING_OUTPUT`] bytes
/// behind, is dropped; the others go on. (Before dropping a client, `send`
/// gives its writer up to 20 ms to hand the queue to the socket: queued
/// bytes may only mean the thread has not run yet.) With no client
/// connected, `send` succeeds and sends nothing.
///
/// `recv` takes turns between clients with data, so a busy one cannot
/// starve the rest, and returns one client's bytes at a time, up to a
/// frame boundary: the start of a frame whose end has not arrived waits in
/// that client's reader, so frames of different clients never interleave.
/// It sees bytes once a reader has passed them on (a zero timeout returns
/// only those), and accepts a client that connects while it waits within
/// 50 ms.
///
/// Dropping the server closes the listener and ends every client's
/// threads: the readers at once, the writers once they have written what
/// was queued (giving up on a client that takes nothing for a second).
pub struct TcpServer {
    listener: TcpListener,
    clients: Vec<Client>,
    /// Raised by the readers.
    signal: Arc<Signal>,
    /// Round-robin start for the next read.
    next_read: usize,
    /// Held by every thread of the server while it runs (the strong count
    /// is one plus the threads still running).
    threads: Arc<()>,
}

impl fmt::Debug for TcpServer {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("TcpServer")
            .field("local_addr", &self.listener.local_addr().ok())
            .field("clients", &self.clients().collect::<Vec<_>>())
            .finish()
    }
}

impl TcpServer {
    /// Listens on `addr` (port 0: the system picks one, see
    /// [`local_addr`](Self::local_addr)).
    pub fn bind(addr: SocketAddr) -> io::Result<Self> {
        let listener = TcpListener::bind(addr)?;
        listener.set_nonblocking(true)?;
        Ok(TcpServer {
            listener,
            clients: Vec::new(),
            signal: Arc::default(),
            next_read: 0,
            threads: Arc::new(()),
        })
    }

    /// The listening address.
    pub fn local_addr(&self) -> io::Result<SocketAddr> {
        self.listener.local_addr()
    }

    /// Addresses of the connected clients (as of the last `send`/`recv`).
    pub fn clients(&self) -> impl Iterator<Item = SocketAddr> + '_ {
        self.clients.iter().filter(|c| !c.dead).map(|c| c.addr)
    }

    /// Accepts every client waiting, without blocking.
    pub fn accept_pending(&mut self) {
        loop {
            match self.listener.accept() {
                Ok((stream, addr)) => {
                    // Threads refused (out of memory or threads): the
                    // client is closed, as if the accept had failed.
                    if let Ok(client) = Client::start(stream, addr, &self.signal, &self.threads) {
                        self.clients.push(client);
                    }
                }
                // A client that gave up before we accepted it: try the next.
                Err(e)
                    if matches!(
                        e.kind(),
                        io::ErrorKind::ConnectionAborted
                            | io::ErrorKind::ConnectionReset
                            | io::ErrorKind::Interrupted
                    ) => {}
                // WouldBlock: none left. Anything else (out of descriptors)
                // is retried on the next call rather than failing the server.
                Err(_) => break,
            }
        }
    }

    /// Removes dead clients, closing their sockets (which ends their
    /// threads).
    fn remove_dead(&mut self) {
        self.clients.retain(|c| {
            if c.dead {
                c.close(Writing::Discard, Shutdown::Both);
            }
            !c.dead
        });
    }

    /// The next client's bytes, in turn (see [`Client::take`]).
    fn read_ready(&mut self, buf: &mut [u8]) -> Option<usize> {
        let count = self.clients.len();
        for k in 0..count {
            let i = (self.next_read + k) % count;
            if let Some((n, whole)) = self.clients[i].take(buf) {
                // A frame cut by a small buffer is finished first.
                self.next_read = if whole { i + 1 } else { i };
                return Some(n);
            }
        }
        None
    }
}

impl Drop for TcpServer {
    fn drop(&mut self) {
        // Ends the readers now (shutting the read side down wakes a blocked
        // read) and lets the writers finish what was queued (or give up on
        // a client that takes nothing for WRITE_CHECK). The listener closes
        // with the server: there is no accept thread to stop.
        for c in &self.clients {
            c.close(Writing::Finish, Shutdown::Read);
        }
    }
}

/// The length of `bytes` up to the end of its last whole frame: bytes that
/// start no frame pass, a frame its header says is incomplete is held.
///
/// The server merges its clients' streams into one: cutting each client's
/// bytes at frame boundaries keeps a frame split across TCP segments from
/// being interleaved with another client's bytes, which would lose it.
fn whole_frames(bytes: &[u8]) -> usize {
    let mut at = 0;
    while at < bytes.len() {
        match frame_len(&bytes[at..]) {
            Ok(n) if n <= bytes.len() - at => at += n,
            Ok(_) | Err(FrameError::Incomplete { .. }) => return at,
            // Not a start byte, or flags that make the length unknowable:
            // the parser decides what these bytes are.
            Err(_) => at += 1,
        }
    }
    at
}

impl Transport for TcpServer {
    fn send(&mut self, frame: &[u8]) -> io::Result<()> {
        self.accept_pending();
        for c in &mut self.clients {
            if !c.dead && !c.send(frame) {
                c.dead = true;
            }
        }
        self.remove_dead();
        Ok(())
    }

    fn recv(&mut self, buf: &mut [u8], timeout: Option<Duration>) -> io::Result<usize> {
        if buf.is_empty() {
            return Ok(0);
        }
        let deadline = Deadline::after(timeout);
        loop {
            self.accept_pending();
            // A reader queues its chunk before it raises the signal: one
            // queued after this look raises it after the clear, which ends
            // the wait below.
            self.signal.clear();
            let got = self.read_ready(buf);
            self.remove_dead();
            if let Some(n) = got {
                return Ok(n);
            }
            let wait = match deadline.remaining() {
                Some(Duration::ZERO) => return Ok(0),
                Some(left) => left.min(ACCEPT_POLL),
                None => ACCEPT_POLL,
            };
            // Raised, or time to accept: either way, look again.
            self.signal.wait(wait);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::test_dialect::Ping;
    use super::*;
    use crate::frame::{encode, Frame, Header, Version, MAX_FRAME_LEN};

    const LIMIT: Option<Duration> = Some(Duration::from_secs(5));

    fn frame(sysid: u8, seq: u8, value: u32) -> Vec<u8> {
        let mut buf = [0u8; MAX_FRAME_LEN];
        let header = Header {
            seq,
            sysid,
            compid: 1,
        };
        let n = encode(Version::V2, header, &Ping { value }, None, &mut buf).unwrap();
        buf[..n].to_vec()
    }

    fn server() -> (TcpServer, SocketAddr) {
        let server = TcpServer::bind(SocketAddr::from(([127, 0, 0, 1], 0))).unwrap();
        let addr = server.local_addr().unwrap();
        (server, addr)
    }

    fn connect(addr: SocketAddr) -> TcpStream {
        let s = TcpStream::connect(addr).unwrap();
        s.set_nodelay(true).unwrap();
        s.set_read_timeout(LIMIT).unwrap();
        s
    }

    /// The frames in `bytes`, which must be whole frames only.
    fn frames(mut bytes: &[u8]) -> Vec<(u8, u8)> {
        let mut out = Vec::new();
        while !bytes.is_empty() {
            let f = Frame::new_checked(bytes).unwrap();
            out.push((f.header().sysid, f.header().seq));
            bytes = &bytes[f.as_bytes().len()..];
        }
        out
    }

    /// `recv` until `want` bytes came (each return whole frames of one
    /// client, as `buf` is large enough).
    fn recv_frames(server: &mut TcpServer, want: usize) -> Vec<Vec<(u8, u8)>> {
        let mut buf = [0u8; 4096];
        let mut got = Vec::new();
        let mut total = 0;
        while total < want {
            let n = server.recv(&mut buf, LIMIT).unwrap();
            assert!(n > 0, "timed out after {total} of {want} bytes");
            total += n;
            got.push(frames(&buf[..n]));
        }
        got
    }

    fn read_exact(stream: &mut TcpStream, n: usize) -> Vec<u8> {
        let mut buf = vec![0u8; n];
        stream.read_exact(&mut buf).unwrap();
        buf
    }

    #[test]
    fn the_server_crosses_threads() {
        fn check<T: Send + Sync>() {}
        check::<TcpServer>();
    }

    #[test]
    fn send_without_clients_succeeds_and_a_new_client_gets_the_next_frame() {
        let (mut server, addr) = server();
        server.send(&frame(1, 0, 1)).unwrap();
        assert_eq!(server.clients().count(), 0);
        // Accepted on the caller's thread: no wait between connect and send.
        let mut client = connect(addr);
        let f = frame(1, 1, 2);
        server.send(&f).unwrap();
        assert_eq!(server.clients().count(), 1);
        assert_eq!(read_exact(&mut client, f.len()), f);
    }

    #[test]
    fn a_client_that_sends_before_the_first_recv_is_heard() {
        let (mut server, addr) = server();
        let mut client = connect(addr);
        let f = frame(7, 0, 42);
        client.write_all(&f).unwrap();
        thread::sleep(Duration::from_millis(30));
        let mut buf = [0u8; 512];
        let n = server.recv(&mut buf, LIMIT).unwrap();
        assert_eq!(&buf[..n], &f[..]);
    }

    #[test]
    fn a_waiting_recv_serves_a_client_that_connects_meanwhile() {
        let (mut server, addr) = server();
        let f = frame(7, 0, 42);
        let sender = {
            let f = f.clone();
            thread::spawn(move || {
                thread::sleep(Duration::from_millis(100));
                let mut client = connect(addr);
                client.write_all(&f).unwrap();
                client
            })
        };
        let started = Instant::now();
        let mut buf = [0u8; 512];
        let n = server.recv(&mut buf, None).unwrap();
        assert_eq!(&buf[..n], &f[..]);
        // 100 ms, plus at most one ACCEPT_POLL, plus scheduling.
        assert!(
            started.elapsed() < Duration::from_secs(1),
            "{:?}",
            started.elapsed()
        );
        drop(sender.join().unwrap());
    }

    #[test]
    fn clients_take_turns() {
        // A has sixteen chunks waiting, B one frame: B's comes second.
        let (mut server, addr) = server();
        let mut a = connect(addr);
        let mut b = connect(addr);
        server.accept_pending();
        let mut a_bytes = 0;
        for seq in 0..16 {
            let f = frame(10, seq, 1);
            a_bytes += f.len();
            a.write_all(&f).unwrap();
            // Separate reads, as far as the timing goes.
            thread::sleep(Duration::from_millis(2));
        }
        let fb = frame(20, 0, 2);
        b.write_all(&fb).unwrap();
        thread::sleep(Duration::from_millis(50));
        let got = recv_frames(&mut server, a_bytes + fb.len());
        let b_at = got.iter().position(|p| p[0].0 == 20).unwrap();
        assert!(b_at <= 1, "B's frame came {b_at}th: {got:?}");
        // A's frames in order, each return from one client only.
        let a_seqs: Vec<u8> = got
            .iter()
            .flatten()
            .filter(|f| f.0 == 10)
            .map(|f| f.1)
            .collect();
        assert_eq!(a_seqs, (0..16).collect::<Vec<u8>>());
        assert!(got.iter().all(|p| p.iter().all(|f| f.0 == p[0].0)));
    }

    #[test]
    fn a_buffer_smaller_than_a_frame_never_interleaves_clients() {
        let (mut server, addr) = server();
        let mut a = connect(addr);
        let mut b = connect(addr);
        server.accept_pending();
        let (fa, fb) = (frame(10, 0, 1), frame(20, 0, 2));
        // A's frame in two pieces around B's, as in the split-frame case.
        a.write_all(&fa[..9]).unwrap();
        thread::sleep(Duration::from_millis(20));
        b.write_all(&fb).unwrap();
        thread::sleep(Duration::from_millis(20));
        a.write_all(&fa[9..]).unwrap();
        thread::sleep(Duration::from_millis(20));
        let mut all = Vec::new();
        let mut buf = [0u8; 5];
        while all.len() < fa.len() + fb.len() {
            let n = server.recv(&mut buf, LIMIT).unwrap();
            assert!(n > 0);
            all.extend_from_slice(&buf[..n]);
        }
        // Both whole (either order): no byte of one inside the other.
        let mut got = frames(&all);
        got.sort();
        assert_eq!(got, [(10, 0), (20, 0)]);
    }

    #[test]
    fn a_stalled_client_is_dropped_while_others_keep_receiving() {
        let (mut server, addr) = server();
        let stalled = connect(addr);
        let mut good = connect(addr);
        server.accept_pending();
        assert_eq!(server.clients().count(), 2);
        // The good client reads everything in a thread of its own.
        let reader = thread::spawn(move || {
            let mut total = 0usize;
            let mut buf = vec![0u8; 64 * 1024];
            loop {
                match good.read(&mut buf) {
                    Ok(0) => return (total, good),
                    Ok(n) => total += n,
                    Err(e) => panic!("good client: {e} after {total} bytes"),
                }
            }
        });
        let block = vec![0x55u8; 16 * 1024];
        let started = Instant::now();
        let mut sent = 0usize;
        while server.clients().count() == 2 {
            let t = Instant::now();
            server.send(&block).unwrap();
            // Generous for a loaded machine; a blocking write would hang.
            assert!(
                t.elapsed() < Duration::from_millis(500),
                "{:?}",
                t.elapsed()
            );
            sent += block.len();
            assert!(
                started.elapsed() < Duration::from_secs(10),
                "not dropped after {sent} bytes"
            );
        }
        assert_eq!(server.clients().count(), 1);
        // The good client got every byte, then more.
        server.send(&block).unwrap();
        sent += block.len();
        let f = frame(1, 0, 9);
        server.send(&f).unwrap();
        sent += f.len();
        assert_eq!(server.clients().count(), 1);
        drop(server);
        let (total, _good) = reader.join().unwrap();
        assert_eq!(total, sent);
        drop(stalled);
    }

    #[test]
    fn dropping_the_server_ends_its_threads_and_frees_the_port() {
        let (mut server, addr) = server();
        let stalled = connect(addr);
        let mut good = connect(addr);
        good.write_all(&frame(3, 0, 1)).unwrap();
        let mut buf = [0u8; 512];
        assert!(server.recv(&mut buf, LIMIT).unwrap() > 0);
        assert_eq!(server.clients().count(), 2);
        let reader = thread::spawn(move || {
            let mut all = Vec::new();
            good.read_to_end(&mut all).map(|_| all)
        });
        // Fill the stalled client's socket until its writer blocks (output
        // stays pending), without passing the cap: a block goes out only
        // when nothing is pending.
        let stalled_addr = stalled.local_addr().unwrap();
        let pending = |server: &TcpServer, addr: Option<SocketAddr>| -> usize {
            let all = server.clients.iter();
            all.filter(|c| addr.is_none_or(|a| a == c.addr))
                .map(|c| {
                    let out = lock(&c.shared.outbox);
                    out.queued.len() + out.writing
                })
                .sum()
        };
        let block = vec![0x55u8; 32 * 1024];
        let mut sent = 0;
        'fill: loop {
            let waiting = Instant::now();
            while pending(&server, None) > 0 {
                if waiting.elapsed() > Duration::from_millis(100) {
                    break 'fill;
                }
                thread::sleep(Duration::from_millis(1));
            }
            server.send(&block).unwrap();
            sent += block.len();
            assert!(sent < 1 << 30, "the stalled client's writer never blocked");
        }
        assert!(pending(&server, Some(stalled_addr)) > 0);
        // A frame queued just before the drop still reaches the good client.
        let f = frame(1, 0, 9);
        server.send(&f).unwrap();
        sent += f.len();
        assert_eq!(server.clients().count(), 2);
        let threads = Arc::downgrade(&server.threads);
        assert_eq!(threads.strong_count(), 1 + 2 * 2);
        drop(server);
        let deadline = Instant::now() + Duration::from_secs(5);
        while threads.strong_count() > 0 {
            let left = threads.strong_count();
            assert!(Instant::now() < deadline, "{left} threads left");
            thread::sleep(Duration::from_millis(10));
        }
        // The port is free again, and the good client got everything, then
        // the end of the stream.
        drop(TcpListener::bind(addr).unwrap());
        let all = reader.join().unwrap().unwrap();
        assert_eq!(all.len(), sent);
        assert_eq!(&all[sent - f.len()..], &f[..]);
        drop(stalled);
    }
}

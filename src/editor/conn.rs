//! The editor's connections, bounded: one thread accepts, one reads every open connection's
//! request without blocking, and a fixed pool of workers answers complete requests.
//!
//! Nothing grows with the number of clients but the list of open connections, capped at
//! [`MAX_CONNECTIONS`]: a connection over the cap closes the oldest one still sending its
//! request (an idle flood cannot lock the page out, it only loses its own oldest sockets). A
//! request's head must arrive within [`HEAD_TIMEOUT`] of the connection and the whole request
//! within [`REQUEST_TIMEOUT`], or it is answered 408 and closed; heads are capped at
//! [`http::MAX_HEAD`] bytes, bodies at [`http::MAX_BODY`] each and [`MAX_BUFFERED`] together.
//! Complete requests wait in a queue of [`QUEUE`] for the [`WORKERS`] workers (503 when it is
//! full), and each answer gets [`WRITE_TIMEOUT`] to be written.

use std::io::{ErrorKind, Read, Write};
use std::net::{TcpListener, TcpStream};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError, SyncSender, TrySendError};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use super::http::{self, BadRequest, Request, Response};

/// The most connections open at once (accepted, their request not yet complete).
pub(crate) const MAX_CONNECTIONS: usize = 256;
/// From the connection to the end of the request's head.
pub(crate) const HEAD_TIMEOUT: Duration = Duration::from_secs(5);
/// From the connection to the end of the request's body.
pub(crate) const REQUEST_TIMEOUT: Duration = Duration::from_secs(30);
/// For writing one answer.
pub(crate) const WRITE_TIMEOUT: Duration = Duration::from_secs(10);
/// The bytes of all requests being read, together.
pub(crate) const MAX_BUFFERED: usize = 64 * 1024 * 1024;
/// The threads that answer requests.
pub(crate) const WORKERS: usize = 4;
/// Complete requests waiting for a worker.
pub(crate) const QUEUE: usize = 32;
/// How often the reader looks at connections that have sent nothing new.
const POLL: Duration = Duration::from_millis(10);

/// A connection whose request is being read.
struct Pending {
    stream: TcpStream,
    since: Instant,
    buf: Vec<u8>,
    /// Once the head is complete: the request, where its body starts and its length.
    head: Option<(Request, usize, usize)>,
}

/// What reading a connection came to.
enum Step {
    /// Nothing more for now.
    Wait,
    /// The request, complete.
    Done(Request),
    /// Answer this refusal and close.
    Refuse(BadRequest),
    /// The client went away.
    Gone,
}

impl Pending {
    fn new(stream: TcpStream) -> Option<Pending> {
        stream.set_nonblocking(true).ok()?;
        Some(Pending {
            stream,
            since: Instant::now(),
            buf: Vec::new(),
            head: None,
        })
    }

    /// Reads what has arrived (never past the request's end) and parses it.
    fn step(&mut self, buffered: usize) -> Step {
        let mut chunk = [0u8; 16 * 1024];
        loop {
            let want = match &self.head {
                None => http::MAX_HEAD.saturating_sub(self.buf.len()).max(1),
                Some((_, start, len)) => (start + len).saturating_sub(self.buf.len()),
            };
            if want == 0 {
                break;
            }
            let n = want.min(chunk.len());
            match self.stream.read(&mut chunk[..n]) {
                Ok(0) => return Step::Gone,
                Ok(got) => self.buf.extend_from_slice(&chunk[..got]),
                Err(e) if e.kind() == ErrorKind::WouldBlock => break,
                Err(e) if e.kind() == ErrorKind::Interrupted => continue,
                Err(_) => return Step::Gone,
            }
            if self.head.is_none() {
                match http::parse_head(&self.buf) {
                    Ok(None) => {}
                    Ok(Some((req, start, len))) => {
                        if buffered + start + len > MAX_BUFFERED {
                            return Step::Refuse(http::bad(503, "the editor is busy: try again"));
                        }
                        self.buf
                            .reserve_exact((start + len).saturating_sub(self.buf.len()));
                        self.head = Some((req, start, len));
                    }
                    Err(bad) => return Step::Refuse(bad),
                }
            }
        }
        match self.head.take() {
            Some((mut req, start, len)) if self.buf.len() >= start + len => {
                let mut body = self.buf.split_off(start);
                body.truncate(len);
                req.body = body;
                Step::Done(req)
            }
            head => {
                self.head = head;
                self.late()
            }
        }
    }

    /// A 408 once the head or the whole request is late.
    fn late(&self) -> Step {
        let age = self.since.elapsed();
        if self.head.is_none() && age > HEAD_TIMEOUT {
            Step::Refuse(http::bad(
                408,
                format!("no complete request head within {HEAD_TIMEOUT:?}"),
            ))
        } else if age > REQUEST_TIMEOUT {
            Step::Refuse(http::bad(
                408,
                format!("no complete request within {REQUEST_TIMEOUT:?}"),
            ))
        } else {
            Step::Wait
        }
    }
}

/// Writes `resp` to a non-blocking stream as far as it goes at once, then closes it (a
/// refusal is small; a client that does not read it loses it).
fn refuse_now(mut stream: TcpStream, bad: &BadRequest) {
    let resp = Response::error(bad.status, &bad.message);
    let mut out = Vec::new();
    if http::write_response(&mut out, &resp).is_ok() {
        let _ = stream.write(&out);
    }
    let _ = stream.shutdown(std::net::Shutdown::Both);
}

/// Serves `listener` until the process ends, answering each request with `answer` on one of
/// [`WORKERS`] threads.
pub(crate) fn serve<F>(listener: TcpListener, answer: F)
where
    F: Fn(&Request) -> Response + Send + Sync + 'static,
{
    let answer = Arc::new(answer);
    let (job_tx, job_rx) = mpsc::sync_channel::<(TcpStream, Request)>(QUEUE);
    let job_rx = Arc::new(Mutex::new(job_rx));
    for i in 0..WORKERS {
        let rx = Arc::clone(&job_rx);
        let answer = Arc::clone(&answer);
        let spawned = std::thread::Builder::new()
            .name(format!("kb-edit-worker-{i}"))
            .spawn(move || work(&rx, answer.as_ref()));
        if let Err(e) = spawned {
            eprintln!("citygen kb edit: a worker thread could not start ({e})");
        }
    }
    let (conn_tx, conn_rx) = mpsc::sync_channel::<TcpStream>(MAX_CONNECTIONS);
    let reader = std::thread::Builder::new()
        .name("kb-edit-reader".into())
        .spawn(move || read_all(&conn_rx, &job_tx));
    if let Err(e) = reader {
        eprintln!("citygen kb edit: the reader thread could not start ({e})");
        return;
    }
    accept(&listener, &conn_tx);
}

/// Accepts connections and hands them to the reader. A failed accept (out of descriptors)
/// waits a little rather than spinning.
fn accept(listener: &TcpListener, conn_tx: &SyncSender<TcpStream>) {
    for conn in listener.incoming() {
        match conn {
            Ok(stream) => {
                if conn_tx.send(stream).is_err() {
                    return;
                }
            }
            Err(_) => std::thread::sleep(Duration::from_millis(20)),
        }
    }
}

/// The reader: takes new connections (closing the oldest unfinished one over the cap), reads
/// every open one without blocking, refuses the bad and the late, and queues complete
/// requests for the workers.
fn read_all(conn_rx: &Receiver<TcpStream>, job_tx: &SyncSender<(TcpStream, Request)>) {
    let mut open: Vec<Pending> = Vec::new();
    loop {
        let first = if open.is_empty() {
            conn_rx.recv().map_err(|_| RecvTimeoutError::Disconnected)
        } else {
            conn_rx.recv_timeout(POLL)
        };
        let new = match first {
            Ok(s) => std::iter::once(s).chain(conn_rx.try_iter()).collect(),
            Err(RecvTimeoutError::Timeout) => Vec::new(),
            Err(RecvTimeoutError::Disconnected) => return,
        };
        for stream in new {
            if open.len() >= MAX_CONNECTIONS {
                let oldest = open.remove(0);
                refuse_now(
                    oldest.stream,
                    &http::bad(
                        503,
                        "too many connections: the oldest unfinished one is closed",
                    ),
                );
            }
            open.extend(Pending::new(stream));
        }
        let mut buffered: usize = open.iter().map(|p| p.buf.capacity()).sum();
        let mut i = 0;
        while i < open.len() {
            let before = open[i].buf.capacity();
            match open[i].step(buffered) {
                Step::Wait => {
                    buffered = buffered + open[i].buf.capacity() - before;
                    i += 1;
                }
                Step::Gone => drop(open.remove(i)),
                Step::Refuse(bad) => refuse_now(open.remove(i).stream, &bad),
                Step::Done(req) => {
                    let stream = open.remove(i).stream;
                    dispatch(job_tx, stream, req);
                }
            }
        }
    }
}

/// Queues a complete request for the workers, or answers 503 when the queue is full.
fn dispatch(job_tx: &SyncSender<(TcpStream, Request)>, stream: TcpStream, req: Request) {
    if stream.set_nonblocking(false).is_err()
        || stream.set_write_timeout(Some(WRITE_TIMEOUT)).is_err()
    {
        return;
    }
    match job_tx.try_send((stream, req)) {
        Ok(()) => {}
        Err(TrySendError::Full((stream, _))) | Err(TrySendError::Disconnected((stream, _))) => {
            let _ = stream.set_nonblocking(true);
            refuse_now(stream, &http::bad(503, "the editor is busy: try again"));
        }
    }
}

/// A worker: answers queued requests, one at a time.
fn work(rx: &Mutex<Receiver<(TcpStream, Request)>>, answer: &dyn Fn(&Request) -> Response) {
    loop {
        let job = {
            let rx = rx.lock().unwrap_or_else(|p| p.into_inner());
            rx.recv()
        };
        let Ok((mut stream, req)) = job else { return };
        let resp = answer(&req);
        let mut out = Vec::new();
        if http::write_response(&mut out, &resp).is_ok() {
            write_by(&mut stream, &out, Instant::now() + WRITE_TIMEOUT);
        }
        let _ = stream.shutdown(std::net::Shutdown::Write);
    }
}

/// Writes `bytes` in pieces until `deadline` (the socket's own timeout bounds each piece):
/// a client that reads slowly gets what it read by then.
fn write_by(stream: &mut TcpStream, bytes: &[u8], deadline: Instant) {
    for piece in bytes.chunks(64 * 1024) {
        if Instant::now() > deadline || stream.write_all(piece).is_err() {
            return;
        }
    }
    let _ = stream.flush();
}

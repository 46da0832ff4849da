//! Output files written past the page cache (Linux `O_DIRECT`), from a background thread.
//!
//! A large run writes gigabytes (the 1M-building LOD2 run 21.8 GB). Through the page cache,
//! once the kernel's background writeback starts (past `dirty_background_ratio` of memory), every
//! buffered `write` pays for it: on the reference machine 2-2.5 s of system time a GB, against
//! 0.2 s a GB before writeback starts and 0.08 s a GB with `O_DIRECT` (measured with `dd`), so a
//! written 1M run spent 63 of its 151 CPU seconds in the kernel. A [`DirectWriter`] fills
//! block-aligned buffers and hands each full one to its own I/O thread, which writes it with
//! `O_DIRECT` at its offset while the writer fills the next: the cores keep deriving while the
//! disk works, and the output does not evict the machine's page cache.
//!
//! The bytes are the same as a buffered write's. The last, partial block is written padded with
//! zeros and the file is then cut to its true length. Where `O_DIRECT` is refused (a file system
//! without it, such as tmpfs, at open or at the first write), the thread goes on with an ordinary
//! descriptor, so the flag is an optimisation, never a requirement.
//!
//! [`DirectWriter::flush`] does not wait for the disk: the writer's data is complete only when
//! the writer has been dropped and [`DirectSink::finish`] has returned `Ok`, which joins the
//! thread and returns the first error of any write.

use std::fs::{File, OpenOptions};
use std::io::{self, Write};
use std::os::unix::fs::{FileExt, OpenOptionsExt};
use std::path::{Path, PathBuf};
use std::sync::mpsc::{channel, Receiver, Sender};
use std::thread::JoinHandle;

/// Alignment of buffers, lengths and offsets for `O_DIRECT` (the largest logical block size of
/// common devices).
const BLOCK: usize = 4096;
/// Bytes of one buffer of a large file (a whole number of blocks).
const CAPACITY: usize = 4 << 20;
/// Bytes of a file's first buffer (a whole number of blocks): each next one is four times
/// larger up to [`CAPACITY`], so that a small file (a tile's 50 KB GLB) costs a small buffer,
/// not 4 MiB cleared for it.
const FIRST: usize = 64 << 10;
/// Buffers handed to the I/O thread and not yet back, at most.
const IN_FLIGHT: usize = 2;

/// A heap buffer of `cap` bytes (a whole number of blocks) whose start is aligned to [`BLOCK`].
struct Aligned {
    mem: Vec<u8>,
    start: usize,
    cap: usize,
}

impl Aligned {
    fn new(cap: usize) -> Aligned {
        let mem = vec![0u8; cap + BLOCK];
        // The heap block does not move when the Vec does, so the offset stays valid.
        let start = mem.as_ptr().align_offset(BLOCK).min(BLOCK);
        Aligned { mem, start, cap }
    }

    fn bytes(&self) -> &[u8] {
        &self.mem[self.start..self.start + self.cap]
    }

    fn bytes_mut(&mut self) -> &mut [u8] {
        &mut self.mem[self.start..self.start + self.cap]
    }
}

/// One buffer to write: its first `len` bytes at `offset` (a multiple of [`BLOCK`]).
struct Job {
    buf: Aligned,
    len: usize,
    offset: u64,
}

/// The writing half: a `Write` that buffers into aligned blocks and sends them to the I/O
/// thread. Dropping it sends the last, partial block.
pub(crate) struct DirectWriter {
    buf: Option<Aligned>,
    len: usize,
    /// File offset of `buf`'s first byte.
    offset: u64,
    jobs: Option<Sender<Job>>,
    done: Receiver<io::Result<Aligned>>,
    spare: Vec<Aligned>,
    in_flight: usize,
}

/// The completing half: joins the I/O thread.
pub(crate) struct DirectSink {
    thread: Option<JoinHandle<io::Result<()>>>,
}

/// Opens `path` (an existing, empty file) for writing with `O_DIRECT` where the system allows
/// it, and starts its I/O thread.
pub(crate) fn open(path: &Path) -> io::Result<(DirectWriter, DirectSink)> {
    let (file, direct) = match OpenOptions::new()
        .write(true)
        .custom_flags(libc::O_DIRECT)
        .open(path)
    {
        Ok(f) => (f, true),
        Err(_) => (OpenOptions::new().write(true).open(path)?, false),
    };
    let (jobs, job_rx) = channel::<Job>();
    let (done_tx, done) = channel::<io::Result<Aligned>>();
    let path = path.to_path_buf();
    let thread = std::thread::Builder::new()
        .name("citygen-write".into())
        .spawn(move || io_thread(file, direct, path, job_rx, done_tx))?;
    Ok((
        DirectWriter {
            buf: Some(Aligned::new(FIRST)),
            len: 0,
            offset: 0,
            jobs: Some(jobs),
            done,
            spare: Vec::new(),
            in_flight: 0,
        },
        DirectSink {
            thread: Some(thread),
        },
    ))
}

/// Writes each job's buffer at its offset, in order, returning the buffers; after the last job,
/// cuts the file to the end of the data. Returns the first error.
fn io_thread(
    mut file: File,
    mut direct: bool,
    path: PathBuf,
    jobs: Receiver<Job>,
    done: Sender<io::Result<Aligned>>,
) -> io::Result<()> {
    let mut end = 0u64;
    let mut failed: Option<io::Error> = None;
    for Job { buf, len, offset } in jobs {
        if failed.is_none() {
            // Whole blocks: the tail is padded with whatever the buffer holds past `len`, and
            // cut off below.
            let padded = len.div_ceil(BLOCK) * BLOCK;
            match write_at(
                &mut file,
                &mut direct,
                &path,
                &buf.bytes()[..padded],
                offset,
            ) {
                Ok(()) => end = offset + len as u64,
                Err(e) => failed = Some(e),
            }
        }
        let reply = match &failed {
            None => Ok(buf),
            Some(e) => Err(io::Error::new(e.kind(), e.to_string())),
        };
        // The writer may be gone (dropped after an error): nothing to tell it then.
        let _ = done.send(reply);
    }
    match failed {
        Some(e) => Err(e),
        None => file.set_len(end),
    }
}

/// `data` at `offset`; if the file system refuses `O_DIRECT` writes, reopens `path` without it
/// and writes there.
fn write_at(
    file: &mut File,
    direct: &mut bool,
    path: &Path,
    data: &[u8],
    offset: u64,
) -> io::Result<()> {
    match file.write_all_at(data, offset) {
        Err(e) if *direct && e.raw_os_error() == Some(libc::EINVAL) => {
            *file = OpenOptions::new().write(true).open(path)?;
            *direct = false;
            file.write_all_at(data, offset)
        }
        r => r,
    }
}

impl DirectWriter {
    /// Sends the full buffer and takes the next one (a spare, a new one, or one the thread gives
    /// back), surfacing the thread's first error.
    fn submit(&mut self) -> io::Result<()> {
        let buf = self
            .buf
            .take()
            .expect("a DirectWriter always holds a buffer");
        let cap = buf.cap;
        self.send(buf, self.len)?;
        self.offset += self.len as u64;
        self.len = 0;
        let next = if cap < CAPACITY {
            // While the buffers grow, each is new (the smaller ones coming back are dropped).
            Aligned::new((cap * 4).min(CAPACITY))
        } else {
            match self.spare.pop() {
                Some(b) => b,
                None if self.in_flight < IN_FLIGHT => Aligned::new(CAPACITY),
                None => self.take_full()?,
            }
        };
        self.buf = Some(next);
        Ok(())
    }

    fn send(&mut self, buf: Aligned, len: usize) -> io::Result<()> {
        let jobs = self.jobs.as_ref().ok_or_else(gone)?;
        jobs.send(Job {
            buf,
            len,
            offset: self.offset,
        })
        .map_err(|_| gone())?;
        self.in_flight += 1;
        // Buffers already written go back to the spares without waiting (the smaller ones
        // of the first growth are dropped).
        while let Ok(r) = self.done.try_recv() {
            self.in_flight -= 1;
            let b = r?;
            if b.cap == CAPACITY {
                self.spare.push(b);
            }
        }
        Ok(())
    }

    /// Waits for a full-size buffer the thread has written (dropping smaller ones).
    fn take_full(&mut self) -> io::Result<Aligned> {
        loop {
            let r = self.done.recv().map_err(|_| gone())?;
            self.in_flight -= 1;
            let b = r?;
            if b.cap == CAPACITY {
                return Ok(b);
            }
        }
    }
}

/// The I/O thread ended early (it panicked): its error is at [`DirectSink::finish`].
fn gone() -> io::Error {
    io::Error::other("the output's writing thread has stopped")
}

impl Write for DirectWriter {
    fn write(&mut self, data: &[u8]) -> io::Result<usize> {
        let buf = self
            .buf
            .as_mut()
            .expect("a DirectWriter always holds a buffer");
        let n = data.len().min(buf.cap - self.len);
        buf.bytes_mut()[self.len..self.len + n].copy_from_slice(&data[..n]);
        self.len += n;
        if self.len == buf.cap {
            self.submit()?;
        }
        Ok(n)
    }

    /// Does not wait for the disk (see the module documentation).
    fn flush(&mut self) -> io::Result<()> {
        Ok(())
    }
}

impl Drop for DirectWriter {
    fn drop(&mut self) {
        if let Some(buf) = self.buf.take() {
            if self.len > 0 {
                // An error here is the thread's, and comes back from `DirectSink::finish`.
                let _ = self.send(buf, self.len);
            }
        }
        // Closing the channel ends the thread once it has written everything.
        self.jobs = None;
    }
}

impl DirectSink {
    /// Waits until every byte of the (dropped) writer is written and the file cut to length;
    /// returns the first error of any write.
    pub(crate) fn finish(mut self) -> io::Result<()> {
        match self.thread.take().map(JoinHandle::join) {
            Some(Ok(r)) => r,
            Some(Err(_)) => Err(io::Error::other("the output's writing thread panicked")),
            None => Ok(()),
        }
    }
}

impl Drop for DirectSink {
    fn drop(&mut self) {
        // A failed run: wait for the thread so that none outlives the temporary file's removal.
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write_in_pieces(path: &Path, data: &[u8], piece: usize) {
        std::fs::write(path, b"").unwrap();
        let (mut w, sink) = open(path).unwrap();
        for c in data.chunks(piece.max(1)) {
            w.write_all(c).unwrap();
        }
        w.flush().unwrap();
        drop(w);
        sink.finish().unwrap();
    }

    #[test]
    fn bytes_are_those_written_for_every_length_around_the_blocks() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("out.bin");
        // The first buffers: FIRST, 4 FIRST, 16 FIRST, then CAPACITY.
        let ramp = FIRST + 4 * FIRST + 16 * FIRST;
        let lengths = [
            0,
            1,
            BLOCK - 1,
            BLOCK,
            BLOCK + 1,
            FIRST - 1,
            FIRST,
            FIRST + 1,
            ramp - 1,
            ramp,
            ramp + 1,
            CAPACITY - 1,
            CAPACITY,
            CAPACITY + 1,
            3 * CAPACITY + 12_345,
        ];
        for len in lengths {
            let data: Vec<u8> = (0..len).map(|i| (i * 7 + i / 251) as u8).collect();
            for piece in [1 << 20, 1000, CAPACITY + 3] {
                if len > 100_000 && piece < 100_000 {
                    continue;
                }
                write_in_pieces(&path, &data, piece);
                let back = std::fs::read(&path).unwrap();
                assert_eq!(back.len(), len, "length {len} in pieces of {piece}");
                assert!(back == data, "bytes of length {len} in pieces of {piece}");
            }
        }
    }

    #[test]
    fn a_file_system_without_o_direct_gets_the_same_bytes() {
        // /dev/shm is tmpfs on Linux, which refuses O_DIRECT at open; elsewhere the test still
        // checks the bytes.
        let dir = match tempfile::tempdir_in("/dev/shm") {
            Ok(d) => d,
            Err(_) => tempfile::tempdir().unwrap(),
        };
        let path = dir.path().join("out.bin");
        let data: Vec<u8> = (0..CAPACITY + 777).map(|i| (i % 253) as u8).collect();
        write_in_pieces(&path, &data, 65_536);
        assert!(std::fs::read(&path).unwrap() == data);
    }

    #[test]
    fn a_refused_o_direct_write_goes_on_without_it() {
        // An unaligned buffer is refused by O_DIRECT with EINVAL, as a file system without it
        // refuses every write: the same fallback.
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("out.bin");
        std::fs::write(&path, b"").unwrap();
        let mut file = OpenOptions::new()
            .write(true)
            .custom_flags(libc::O_DIRECT)
            .open(&path)
            .expect("the test's temporary folder takes O_DIRECT");
        let mut direct = true;
        let data: Vec<u8> = (0..BLOCK + 10).map(|i| i as u8).collect();
        // An odd length and address: no device takes that directly.
        write_at(&mut file, &mut direct, &path, &data[3..BLOCK + 4], 0).unwrap();
        assert!(!direct, "the unaligned write fell back");
        assert_eq!(std::fs::read(&path).unwrap(), &data[3..BLOCK + 4]);
    }

    #[test]
    fn a_write_error_comes_back_from_finish() {
        // /dev/full refuses every write with ENOSPC.
        let (mut w, sink) = open(Path::new("/dev/full")).unwrap();
        let data = vec![1u8; 3 * CAPACITY];
        let early = w.write_all(&data);
        drop(w);
        let late = sink.finish();
        assert!(
            early.is_err() || late.is_err(),
            "a write to /dev/full must fail somewhere"
        );
        assert!(late.is_err(), "finish returns the first error");
    }
}

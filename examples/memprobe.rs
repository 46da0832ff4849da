//! Where a run's memory is live (issue 46): the `citygen` command line run in this process
//! under a counting global allocator, with the bytes allocated and not yet freed (the live
//! heap, not the resident set: freed pages an allocator keeps are not counted) printed every
//! `MEMPROBE_MS` milliseconds (default 250) to stderr.
//!
//! ```text
//! cargo run --release --example memprobe -- --osm target/bench-inputs/jittered-1000000.osm.pbf \
//!     --kb knowledge_base/kb.xml --lod 2 --tile 1000 --dry-run --ifc o/a.ifc ...
//! ```
//!
//! Each line is `probe SECONDS live MIB peak MIB`: the live heap at the sample and the most it
//! reached since the sample before. The run's own summary (its `memory:` line, each stage's end
//! in seconds from the same start within a few milliseconds) lines the samples up with the
//! stages. The allocator under the count is the binary's (mimalloc, feature `mimalloc`), so
//! the run's resident memory is what `citygen` would have; counting costs a few per cent of CPU.

use std::alloc::{GlobalAlloc, Layout};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

#[cfg(feature = "mimalloc")]
const INNER: mimalloc::MiMalloc = mimalloc::MiMalloc;
#[cfg(not(feature = "mimalloc"))]
const INNER: std::alloc::System = std::alloc::System;

/// Bytes allocated and not yet freed.
static LIVE: AtomicUsize = AtomicUsize::new(0);
/// The most `LIVE` reached since the last sample.
static PEAK: AtomicUsize = AtomicUsize::new(0);

struct Counting;

fn grew(by: usize) {
    let now = LIVE.fetch_add(by, Ordering::Relaxed) + by;
    PEAK.fetch_max(now, Ordering::Relaxed);
}

// SAFETY: every call is passed on unchanged to the inner allocator; only counters are added.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let p = INNER.alloc(layout);
        if !p.is_null() {
            grew(layout.size());
        }
        p
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        INNER.dealloc(ptr, layout);
        LIVE.fetch_sub(layout.size(), Ordering::Relaxed);
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let p = INNER.realloc(ptr, layout, new_size);
        if !p.is_null() {
            if new_size >= layout.size() {
                grew(new_size - layout.size());
            } else {
                LIVE.fetch_sub(layout.size() - new_size, Ordering::Relaxed);
            }
        }
        p
    }
}

#[global_allocator]
static ALLOC: Counting = Counting;

fn main() -> std::process::ExitCode {
    let every = std::env::var("MEMPROBE_MS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(250u64);
    let start = Instant::now();
    std::thread::spawn(move || loop {
        std::thread::sleep(Duration::from_millis(every));
        let live = LIVE.load(Ordering::Relaxed);
        let peak = PEAK.swap(live, Ordering::Relaxed).max(live);
        eprintln!(
            "probe {:.2} live {} peak {}",
            start.elapsed().as_secs_f64(),
            live >> 20,
            peak >> 20
        );
    });
    match citygen::app::run(citygen::app::parse()) {
        Ok(outcome) => std::process::ExitCode::from(outcome.exit_code()),
        Err(e) => {
            eprintln!("{e}");
            std::process::ExitCode::from(e.exit_code())
        }
    }
}

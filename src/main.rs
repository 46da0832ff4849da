//! The `citygen` binary: the global allocator, then [`citygen::app`] runs the command line
//! (arguments, the commands, what they print) and its error gives the exit code.

#![forbid(unsafe_code)]

use std::process::ExitCode;

use citygen::app;

/// mimalloc (feature `mimalloc`, on by default): the derivation allocates many small
/// short-lived vectors per building, and glibc's malloc took about 30 % of a LOD2 profile.
#[cfg(feature = "mimalloc")]
#[global_allocator]
static ALLOC: mimalloc::MiMalloc = mimalloc::MiMalloc;

fn main() -> ExitCode {
    match app::run(app::parse()) {
        Ok(outcome) => ExitCode::from(outcome.exit_code()),
        Err(e) => {
            let message = e.to_string();
            if !message.is_empty() {
                eprintln!("{message}");
            }
            ExitCode::from(e.exit_code())
        }
    }
}

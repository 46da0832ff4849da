//! The second line of "no panic on input": a panic (a bug, in citygen or in a crate it calls)
//! caught where one building or one file is at stake, and turned into an error message.

use std::panic::{catch_unwind, AssertUnwindSafe};

/// A panic caught by [`caught`]: what was being done and the panic's message. It reads
/// "internal error while {what}: {panic message} (a citygen bug: please report it)".
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("internal error while {what}: {message} (a citygen bug: please report it)")]
pub(crate) struct Panicked {
    /// What was being done, e.g. "deriving the building".
    pub what: String,
    /// The text the panic was raised with ("no message" when it had none).
    pub message: String,
}

/// Runs `f`; a panic inside it becomes a [`Panicked`] error. `what` is built only when a panic
/// happened.
pub fn caught<T, W: std::fmt::Display>(
    what: impl FnOnce() -> W,
    f: impl FnOnce() -> T,
) -> Result<T, Panicked> {
    catch_unwind(AssertUnwindSafe(f)).map_err(|payload| Panicked {
        what: what().to_string(),
        message: panic_message(payload.as_ref()),
    })
}

/// The text a panic was raised with (`panic!` gives a `&str` or a `String`).
fn panic_message(payload: &(dyn std::any::Any + Send)) -> String {
    payload
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "no message".to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_panic_becomes_an_error_naming_what_was_done_and_the_message() {
        let r: Result<(), Panicked> =
            caught(|| "deriving the building", || panic!("ring {} bad", 7));
        let e = r.unwrap_err().to_string();
        assert!(
            e.starts_with("internal error while deriving the building: ring 7 bad"),
            "{e}"
        );
        assert!(e.ends_with("(a citygen bug: please report it)"), "{e}");
        let r: Result<(), Panicked> = caught(|| "x", || panic!("static text"));
        assert!(r.unwrap_err().to_string().contains(": static text ("));
        let r: Result<(), Panicked> = caught(|| "x", || std::panic::panic_any(42_u8));
        assert!(r.unwrap_err().to_string().contains(": no message ("));
    }

    #[test]
    fn without_a_panic_the_value_passes_through_and_what_is_not_built() {
        let what = || -> &str { panic!("`what` built without a panic") };
        assert_eq!(caught(what, || 3), Ok(3));
        assert_eq!(caught(|| "x", || Err::<(), _>("plain")), Ok(Err("plain")));
    }
}

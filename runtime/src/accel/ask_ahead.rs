//! Rendering that asks ahead instead of waiting: while a render thread runs
//! [`without_waiting`], a demand-loaded object (or part of an object's BVH) that a ray reaches
//! and this process does not hold is asked for ([`MeshSource::ask_ahead`]) and treated as
//! missed, and the call reports that it missed something. Its result is then wrong and must be
//! thrown away: a distributed worker renders the unit again later, once what it asked for has
//! come, and renders other units meanwhile, so that one round trip to the master covers what a
//! whole unit reaches and its wait overlaps rendering (the paper's latency hiding, by units
//! instead of threads).
//!
//! A shader's `printf` output is held until the call ends: written if nothing was missed,
//! dropped with the result otherwise (the unit's next render prints it).
//!
//! Invariant: nothing that outlives the call may be computed from a missed object. State that is
//! shared across units and computed lazily from traced rays (a frame's virtual lights and photon
//! maps, a light's cached row) is computed inside [`waiting`], which waits as usual.
//!
//! [`MeshSource::ask_ahead`]: super::object::MeshSource::ask_ahead

use std::cell::{Cell, RefCell};
use std::io::Write;

thread_local! {
    /// Whether this thread asks ahead, and whether it missed something since it started to.
    static STATE: Cell<Mode> = const { Cell::new(Mode::Waits) };
    /// Output printed since this thread started to ask ahead.
    static HELD: RefCell<Vec<u8>> = const { RefCell::new(Vec::new()) };
}

#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Mode {
    Waits,
    AsksAhead { missed: bool },
}

/// Runs `f` on this thread asking ahead for what it reaches and does not hold; returns its result
/// and whether it missed something (then the result is not to be used).
pub fn without_waiting<R>(f: impl FnOnce() -> R) -> (R, bool) {
    let before = STATE.with(|s| s.replace(Mode::AsksAhead { missed: false }));
    let outer = HeldOutput(Some(HELD.with(|h| std::mem::take(&mut *h.borrow_mut()))));
    let restore = Restore(before);
    let r = f();
    let missed = STATE.with(|s| s.get()) == Mode::AsksAhead { missed: true };
    let output = outer.give_back();
    drop(restore);
    if !missed && !output.is_empty() {
        if asks_ahead() {
            HELD.with(|h| h.borrow_mut().extend_from_slice(&output));
        } else {
            let _ = std::io::stdout().lock().write_all(&output);
        }
    }
    (r, missed)
}

/// Holds `text`, printed by a shader on a thread asking ahead, until the call ends; returns
/// whether it did (else the caller writes it).
pub(crate) fn hold_output(text: &str) -> bool {
    asks_ahead() && {
        HELD.with(|h| h.borrow_mut().extend_from_slice(text.as_bytes()));
        true
    }
}

/// Runs `f` on this thread waiting for what it reaches, as outside [`without_waiting`]: for state
/// that outlives the unit being rendered.
pub fn waiting<R>(f: impl FnOnce() -> R) -> R {
    let before = STATE.with(|s| s.replace(Mode::Waits));
    let restore = Restore(before);
    let r = f();
    drop(restore);
    r
}

/// Whether this thread asks ahead instead of waiting.
#[inline]
pub(crate) fn asks_ahead() -> bool {
    STATE.with(|s| s.get() != Mode::Waits)
}

/// Notes that this thread, asking ahead, went on without something it reached.
pub(crate) fn missed() {
    STATE.with(|s| {
        if let Mode::AsksAhead { .. } = s.get() {
            s.set(Mode::AsksAhead { missed: true });
        }
    });
}

/// The output held by the calls around this one, given back when it ends, a panic included
/// (then what the call held is dropped).
struct HeldOutput(Option<Vec<u8>>);

impl HeldOutput {
    /// Gives the outer calls' output back; returns this call's.
    fn give_back(mut self) -> Vec<u8> {
        let outer = self.0.take().unwrap_or_default();
        HELD.with(|h| std::mem::replace(&mut *h.borrow_mut(), outer))
    }
}

impl Drop for HeldOutput {
    fn drop(&mut self) {
        if let Some(outer) = self.0.take() {
            HELD.with(|h| *h.borrow_mut() = outer);
        }
    }
}

/// Puts the thread's mode back as it was, however the call ends (a panic included).
struct Restore(Mode);

impl Drop for Restore {
    fn drop(&mut self) {
        let outer = self.0;
        STATE.with(|s| {
            // What an inner call missed counts for the outer call too.
            let missed_inside = s.get() == Mode::AsksAhead { missed: true };
            s.set(match outer {
                Mode::AsksAhead { missed } => Mode::AsksAhead { missed: missed || missed_inside },
                Mode::Waits => Mode::Waits,
            })
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_miss_is_reported_by_the_call_it_happened_in_and_the_mode_is_restored() {
        assert!(!asks_ahead());
        let ((), missed) = without_waiting(|| {
            assert!(asks_ahead());
            waiting(|| assert!(!asks_ahead()));
            assert!(asks_ahead());
        });
        assert!(!missed);
        let ((), missed) = without_waiting(missed_here);
        assert!(missed);
        assert!(!asks_ahead());
        // A miss outside any call is no miss of a later call.
        missed_here();
        let ((), missed) = without_waiting(|| {});
        assert!(!missed);
    }

    #[test]
    fn output_is_held_while_asking_ahead_and_kept_only_where_nothing_was_missed() {
        assert!(!hold_output("written at once"));
        let ((), _) = without_waiting(|| {
            assert!(hold_output("held"));
            let ((), missed) = without_waiting(|| {
                assert!(hold_output(" and dropped"));
                missed_here();
            });
            assert!(missed);
            let ((), missed) = without_waiting(|| assert!(hold_output(" and kept")));
            assert!(!missed);
            assert_eq!(HELD.with(|h| h.borrow().clone()), b"held and kept");
        });
        assert!(HELD.with(|h| h.borrow().is_empty()));
    }

    #[test]
    fn a_panic_inside_leaves_the_thread_waiting_again() {
        let caught = std::panic::catch_unwind(|| {
            without_waiting(|| {
                hold_output("never written");
                panic!("a shader's panic")
            })
        });
        assert!(caught.is_err());
        assert!(!asks_ahead());
        assert!(HELD.with(|h| h.borrow().is_empty()));
    }

    fn missed_here() {
        missed();
    }
}

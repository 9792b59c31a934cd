//! Per-thread stacks of scratch buffers reused from batch to batch. A buffer allocated afresh for
//! every batch came back from the allocator as newly faulted pages; a stack, because shading
//! recurses (a surface traces rays whose hits are shaded in batches of their own).

use std::cell::RefCell;
use std::thread::LocalKey;

/// Buffers kept per stack: as deep as shading recursion goes; more are dropped.
const KEPT: usize = 16;

/// A buffer from `stack` (a default one when it is empty); hand it back with [`give`].
pub(super) fn take<T: Default>(stack: &'static LocalKey<RefCell<Vec<T>>>) -> T {
    stack.try_with(|s| s.try_borrow_mut().ok().and_then(|mut s| s.pop())).ok().flatten().unwrap_or_default()
}

/// Returns `buffer` to `stack`, unless the stack is full, borrowed, or gone (a thread exiting).
pub(super) fn give<T>(stack: &'static LocalKey<RefCell<Vec<T>>>, buffer: T) {
    let _ = stack.try_with(|s| {
        if let Ok(mut s) = s.try_borrow_mut() {
            if s.len() < KEPT {
                s.push(buffer);
            }
        }
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    thread_local! {
        static STACK: RefCell<Vec<Vec<u8>>> = const { RefCell::new(Vec::new()) };
    }

    #[test]
    fn buffers_come_back_last_in_first_out_and_the_stack_stays_bounded() {
        assert!(take(&STACK).is_empty(), "an empty stack gives a default buffer");
        give(&STACK, vec![1]);
        give(&STACK, vec![2]);
        assert_eq!(take(&STACK), vec![2]);
        assert_eq!(take(&STACK), vec![1]);
        for k in 0..2 * KEPT {
            give(&STACK, vec![k as u8]);
        }
        assert_eq!(STACK.with(|s| s.borrow().len()), KEPT);
        // Given while the stack is borrowed: dropped, not a panic.
        STACK.with(|s| {
            let _held = s.borrow_mut();
            give(&STACK, vec![9]);
            assert!(take(&STACK).is_empty());
        });
    }
}

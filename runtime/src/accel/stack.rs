//! A traversal stack that lives on the machine stack and is not initialised on creation (traversal
//! runs once per ray, so zeroing a few hundred bytes each time would show in profiles). When a BVH
//! is deeper than the fixed part allows, further entries spill to a heap vector.
//!
//! Invariant: entries `buf[..len]` are initialised; `spill` holds entries pushed while `buf` was
//! full, so they are above all of `buf` and are popped first.

use std::mem::MaybeUninit;

pub(crate) struct Stack<T: Copy, const N: usize> {
    buf: [MaybeUninit<T>; N],
    len: usize,
    spill: Vec<T>,
}

impl<T: Copy, const N: usize> Stack<T, N> {
    #[inline(always)]
    pub fn new() -> Self {
        Stack { buf: [const { MaybeUninit::uninit() }; N], len: 0, spill: Vec::new() }
    }

    #[inline(always)]
    pub fn push(&mut self, v: T) {
        if self.len < N {
            self.buf[self.len].write(v);
            self.len += 1;
        } else {
            self.spill.push(v);
        }
    }

    #[inline(always)]
    pub fn pop(&mut self) -> Option<T> {
        if !self.spill.is_empty() {
            return self.spill.pop();
        }
        if self.len == 0 {
            return None;
        }
        self.len -= 1;
        // SAFETY: `buf[..len]` is initialised (module invariant), and `len` was just decremented
        // from a value `<= N`, so `buf[self.len]` is in bounds and initialised.
        Some(unsafe { self.buf[self.len].assume_init() })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lifo_across_the_spill() {
        let mut s: Stack<u32, 4> = Stack::new();
        for i in 0..10 {
            s.push(i);
        }
        for i in (0..10).rev() {
            assert_eq!(s.pop(), Some(i));
        }
        assert_eq!(s.pop(), None);
    }
}

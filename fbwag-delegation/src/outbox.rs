//! A fixed-capacity action queue: the machines allocate nothing.

/// Actions waiting for `poll_action`. No single call emits more than four;
/// the contract is to drain after every `handle_*` call. Overflowing means
/// a caller broke it: a debug assertion says so (release builds drop the
/// newest action rather than panic).
#[derive(Debug, Clone)]
pub(crate) struct Outbox<T: Copy, const N: usize> {
    items: [Option<T>; N],
    head: usize,
    len: usize,
}

impl<T: Copy, const N: usize> Outbox<T, N> {
    pub(crate) const fn new() -> Self {
        Outbox {
            items: [None; N],
            head: 0,
            len: 0,
        }
    }

    pub(crate) fn push(&mut self, item: T) {
        debug_assert!(self.len < N, "outbox overflow");
        if self.len < N {
            self.items[(self.head + self.len) % N] = Some(item);
            self.len += 1;
        }
    }

    /// Items waiting.
    pub(crate) fn len(&self) -> usize {
        self.len
    }

    pub(crate) fn pop(&mut self) -> Option<T> {
        if self.len == 0 {
            return None;
        }
        let item = self.items[self.head].take();
        self.head = (self.head + 1) % N;
        self.len -= 1;
        item
    }
}

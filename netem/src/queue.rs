//! [`DueQueue`]: items waiting for their due time, released in `(due, seq)` order.
//!
//! Keyed by the pair, never by the time alone: two packets due in the same nanosecond are both
//! kept and leave in sequence order (a map keyed by timestamp would silently lose one — the
//! rs-lag anti-pattern in network notes §2.1).

use std::cmp::{Ordering, Reverse};
use std::collections::BinaryHeap;

/// A min-heap of items keyed by `(due_ns, seq)`.
#[derive(Debug)]
pub struct DueQueue<T> {
    heap: BinaryHeap<Reverse<Entry<T>>>,
}

/// An item leaving a [`DueQueue`].
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Due<T> {
    /// When it was due [ns].
    pub due_ns: u64,
    /// Its sequence number (unique per queue, chosen by the caller).
    pub seq: u64,
    /// The item.
    pub item: T,
}

#[derive(Debug)]
struct Entry<T>(Due<T>);

impl<T> PartialEq for Entry<T> {
    fn eq(&self, other: &Self) -> bool {
        self.key() == other.key()
    }
}
impl<T> Eq for Entry<T> {}
impl<T> PartialOrd for Entry<T> {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}
impl<T> Ord for Entry<T> {
    fn cmp(&self, other: &Self) -> Ordering {
        self.key().cmp(&other.key())
    }
}
impl<T> Entry<T> {
    fn key(&self) -> (u64, u64) {
        (self.0.due_ns, self.0.seq)
    }
}

impl<T> Default for DueQueue<T> {
    fn default() -> Self {
        Self::new()
    }
}

impl<T> DueQueue<T> {
    /// An empty queue.
    pub fn new() -> Self {
        Self {
            heap: BinaryHeap::new(),
        }
    }

    /// Queues `item`, due at `due_ns`, with sequence number `seq` (the tie-break).
    pub fn push(&mut self, due_ns: u64, seq: u64, item: T) {
        self.heap.push(Reverse(Entry(Due { due_ns, seq, item })));
    }

    /// The earliest due time, if any item waits.
    pub fn next_due_ns(&self) -> Option<u64> {
        self.heap.peek().map(|Reverse(entry)| entry.0.due_ns)
    }

    /// Removes and returns the first item if it is due at `now_ns`.
    pub fn pop_due(&mut self, now_ns: u64) -> Option<Due<T>> {
        if self.next_due_ns()? > now_ns {
            return None;
        }
        self.heap.pop().map(|Reverse(Entry(due))| due)
    }

    /// Items waiting.
    pub fn len(&self) -> usize {
        self.heap.len()
    }

    /// No item waits.
    pub fn is_empty(&self) -> bool {
        self.heap.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn releases_by_due_then_seq_and_keeps_ties() {
        let mut q = DueQueue::new();
        q.push(20, 1, "b");
        q.push(10, 3, "c");
        q.push(20, 0, "a");
        q.push(10, 2, "d");
        assert_eq!(q.pop_due(9), None);
        let order: Vec<&str> = std::iter::from_fn(|| q.pop_due(20))
            .map(|d| d.item)
            .collect();
        assert_eq!(order, ["d", "c", "a", "b"]);
        assert!(q.is_empty());
    }
}

//! The collapse queue: an indexed binary min-heap of edges by the cost of their cheapest
//! placement, re-keyed in place when a collapse changes an edge.

use super::NONE;

/// Binary min-heap of edges by cost that knows where each edge sits, so that a cost can change
/// or an edge leave in place. Order is `(cost, edge)`: ties go to the lower edge number.
pub(super) struct EdgeQueue {
    /// `(key, edge)`; the key is the cost's bits remapped so that integer order is the
    /// order of [`f64::total_cmp`], which keeps comparisons cheap.
    heap: Vec<(u64, u32)>,
    /// Position of each edge in `heap`, or [`NONE`].
    slot: Vec<u32>,
}

impl EdgeQueue {
    pub(super) fn new(edges: usize) -> Self {
        EdgeQueue { heap: Vec::with_capacity(edges), slot: vec![NONE; edges] }
    }

    pub(super) fn key(cost: f64) -> u64 {
        let bits = cost.to_bits();
        if bits >> 63 == 1 {
            !bits
        } else {
            bits | 1 << 63
        }
    }

    pub(super) fn cost(key: u64) -> f64 {
        f64::from_bits(if key >> 63 == 1 { key & !(1 << 63) } else { !key })
    }

    /// The cheapest edge and its cost.
    pub(super) fn front(&self) -> Option<(u32, f64)> {
        self.heap.first().map(|&(k, e)| (e, Self::cost(k)))
    }

    /// The cost of the second cheapest edge (infinite when there is none).
    pub(super) fn runner_up(&self) -> f64 {
        let second = self.heap[1.min(self.heap.len())..self.heap.len().min(3)].iter().min();
        second.map_or(f64::INFINITY, |&(k, _)| Self::cost(k))
    }

    /// Queues `edge` at `cost`, or moves it there if it is queued already.
    pub(super) fn set(&mut self, edge: u32, cost: f64) {
        let item = (Self::key(cost), edge);
        match self.slot[edge as usize] {
            NONE => {
                self.heap.push(item);
                self.sift_up(self.heap.len() - 1);
            }
            i => {
                let old = std::mem::replace(&mut self.heap[i as usize], item);
                self.restore(i as usize, old);
            }
        }
    }

    /// Takes `edge` out of the queue if it is there.
    pub(super) fn remove(&mut self, edge: u32) {
        let i = self.slot[edge as usize];
        if i == NONE {
            return;
        }
        self.slot[edge as usize] = NONE;
        let last = self.heap.pop().expect("a queued edge is in the heap");
        if (i as usize) < self.heap.len() {
            let old = std::mem::replace(&mut self.heap[i as usize], last);
            self.restore(i as usize, old);
        }
    }

    /// Re-establishes heap order after the item at `i` replaced `old`.
    pub(super) fn restore(&mut self, i: usize, old: (u64, u32)) {
        if self.heap[i] < old {
            self.sift_up(i);
        } else {
            self.sift_down(i);
        }
    }

    pub(super) fn place(&mut self, i: usize, item: (u64, u32)) {
        self.heap[i] = item;
        self.slot[item.1 as usize] = i as u32;
    }

    pub(super) fn sift_up(&mut self, mut i: usize) {
        let item = self.heap[i];
        while i > 0 {
            let parent = (i - 1) / 2;
            if self.heap[parent] <= item {
                break;
            }
            self.place(i, self.heap[parent]);
            i = parent;
        }
        self.place(i, item);
    }

    pub(super) fn sift_down(&mut self, mut i: usize) {
        let item = self.heap[i];
        let n = self.heap.len();
        loop {
            let left = 2 * i + 1;
            if left >= n {
                break;
            }
            let child =
                if left + 1 < n && self.heap[left + 1] < self.heap[left] { left + 1 } else { left };
            if item <= self.heap[child] {
                break;
            }
            self.place(i, self.heap[child]);
            i = child;
        }
        self.place(i, item);
    }
}

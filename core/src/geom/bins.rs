//! Items sorted into bins by a counting sort (compressed rows), keeping their order within
//! each bin: the faces of the screen tiles in `render` and of the texel bands in `transfer`.

/// Bin `b` holds `items[starts[b]..starts[b + 1]]`.
pub struct Bins {
    starts: Vec<usize>,
    items: Vec<u32>,
}

impl Bins {
    /// `count` bins of the `(bin, item)` pairs of `pairs`, each bin's items in the order the
    /// pairs come (the iterator is walked twice: once to count, once to place). Panics if a
    /// bin is `count` or more.
    pub fn new<I: Iterator<Item = (u32, u32)>>(count: usize, pairs: impl Fn() -> I) -> Self {
        let mut starts = vec![0usize; count + 1];
        for (b, _) in pairs() {
            starts[b as usize + 1] += 1;
        }
        for b in 0..count {
            starts[b + 1] += starts[b];
        }
        let mut next = starts.clone();
        let mut items = vec![0u32; starts[count]];
        for (b, item) in pairs() {
            items[next[b as usize]] = item;
            next[b as usize] += 1;
        }
        Self { starts, items }
    }

    /// The items of bin `b`, in order.
    pub fn of(&self, b: usize) -> &[u32] {
        &self.items[self.starts[b]..self.starts[b + 1]]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn items_keep_their_order_within_each_bin() {
        let pairs = [(2, 7), (0, 1), (2, 3), (1, 9), (0, 4)];
        let bins = Bins::new(4, || pairs.iter().copied());
        assert_eq!(bins.of(0), [1, 4]);
        assert_eq!(bins.of(1), [9]);
        assert_eq!(bins.of(2), [7, 3]);
        assert!(bins.of(3).is_empty());
    }
}

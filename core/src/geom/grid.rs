//! The integer position grid over the sequence bounding box.
//!
//! Every geometric stage after this one works in *grid units*: coordinates relative to the
//! box corner divided by the quantization step, so that one unit is one quantization step
//! of the base mesh positions. Only the output is mapped back to the input's units.

/// A cubic grid of `2^bits` steps along the largest side of a bounding box.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Grid {
    pub origin: [f64; 3],
    pub step: f64,
    pub bits: u32,
}

/// Position bit depths the codec accepts.
pub const BITS_RANGE: std::ops::RangeInclusive<u32> = 8..=20;

impl Grid {
    /// The grid whose `2^bits - 1` steps span the largest side of the box `[min, max]`.
    /// A box of zero size gets step 1 so that every position maps to the origin.
    pub fn over_box(min: [f64; 3], max: [f64; 3], bits: u32) -> Self {
        let side = (0..3).map(|k| max[k] - min[k]).fold(0.0f64, f64::max);
        let levels = ((1u64 << bits) - 1) as f64;
        let step = if side > 0.0 { side / levels } else { 1.0 };
        Self { origin: min, step, bits }
    }

    /// The `bits`-bit grid made of every `2^(self.bits - bits)`-th point of this one,
    /// expressed in this grid's units (so `to_grid` and `to_world` convert between the two).
    pub fn coarser(&self, bits: u32) -> Self {
        debug_assert!(bits <= self.bits);
        Self { origin: [0.0; 3], step: (1u64 << (self.bits - bits)) as f64, bits }
    }

    /// Largest integer coordinate.
    pub fn max_coord(&self) -> u32 {
        ((1u64 << self.bits) - 1) as u32
    }

    /// Position in grid units (not rounded).
    pub fn to_grid(&self, p: [f64; 3]) -> [f64; 3] {
        std::array::from_fn(|k| (p[k] - self.origin[k]) / self.step)
    }

    /// Nearest integer grid point, clamped into the grid.
    pub fn quantize(&self, g: [f64; 3]) -> [u32; 3] {
        let hi = self.max_coord() as f64;
        g.map(|c| c.round().clamp(0.0, hi) as u32)
    }

    /// Grid units back to the input's units.
    pub fn to_world(&self, g: [f64; 3]) -> [f64; 3] {
        std::array::from_fn(|k| self.origin[k] + g[k] * self.step)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn corners_map_to_the_ends_of_the_grid_and_back() {
        let g = Grid::over_box([-1.0, 0.0, 2.0], [3.0, 1.0, 2.5], 12);
        assert_eq!(g.quantize(g.to_grid([-1.0, 0.0, 2.0])), [0, 0, 0]);
        assert_eq!(g.quantize(g.to_grid([3.0, 1.0, 2.5]))[0], 4095);
        let p = g.to_world([4095.0, 0.0, 0.0]);
        assert!((p[0] - 3.0).abs() < 1e-12);
        assert_eq!(g.quantize([-5.0, 1e9, 7.4]), [0, 4095, 7]);
    }

    #[test]
    fn a_flat_box_still_has_a_usable_step() {
        let g = Grid::over_box([1.0; 3], [1.0; 3], 10);
        assert_eq!(g.step, 1.0);
    }

    #[test]
    fn a_coarser_grid_takes_every_nth_point_and_clamps_to_its_own_range() {
        let g = Grid::over_box([0.0; 3], [1.0; 3], 12);
        let c = g.coarser(10);
        assert_eq!(c.quantize(c.to_grid([8.0, 9.0, 4095.0])), [2, 2, 1023]);
        assert_eq!(c.to_world([3.0, 0.0, 1023.0]), [12.0, 0.0, 4092.0]);
        assert_eq!(g.coarser(12).to_grid([5.0; 3]), [5.0; 3]);
    }
}

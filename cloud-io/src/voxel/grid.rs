//! [`VoxelGrid`]: the voxel grid of a camera stream, without hashing and without a comparison
//! sort.
//!
//! One read of the points gives their bounding box and from it each axis's range of voxel
//! indices (`⌊c / s⌋` is non-decreasing in `c`, so the box's corners hold the least and the
//! greatest index). Then the points are grouped into voxels one of two ways, and the groups'
//! centroids emitted; both give [`super::voxel_downsample`]'s result bit for bit (each voxel's
//! points summed in `f64` from 0 in input order, voxels in index order):
//! - **dense**, when the box holds at most `2·n + 65,536` voxels (a camera's surface: a
//!   0.6 × 0.5 m table at 3 mm is 207 × 157 × 2): a slot per voxel of the box numbers the voxels
//!   in the order of their first points and gives each point its voxel's number; the sums then
//!   run over the points in order, and the slots, read in index order, emit them;
//! - **sorted**, otherwise: each point's voxel index relative to the box's lowest, packed into
//!   as few bits as the ranges need (`i` above `j` above `k`: the packed order is the
//!   lexicographic one) above the point's index; a least-significant-digit radix sort of those
//!   words ([`super::radix`]; stable, so a voxel's points stay in input order); one run over
//!   the sorted words sums each voxel.
//!
//! Grouping alone counts the voxels, which is all a round of the point budget needs: its
//! centroids are summed once, at the edge the rounds end on.
//!
//! A cloud neither way takes (a non-finite coordinate; a voxel index beyond ±2^51; key and
//! point-index bits beyond 64, e.g. 300,000 points over 2^45 voxels) goes to
//! [`super::voxel_downsample`] itself, which also names the point of any error.

use super::{VoxelError, initial_voxel, radix, voxel_downsample};

/// [`voxel_downsample`] with buffers kept between calls, for a camera stream. The output is the
/// same, bit for bit: centroids summed in `f64` in input order, ordered by voxel index. The dense
/// and sorted ways allocate only while their buffers grow to the largest frame seen; a frame
/// neither fits (too sparse a box for the slots, too many voxels for the sort's key) takes
/// [`voxel_downsample`] itself, which allocates its output each time.
#[derive(Debug, Default)]
pub struct VoxelGrid {
    /// Dense: per voxel of the box, its number (in the order of first points), or [`EMPTY`].
    slots: Vec<u32>,
    /// Dense: per point, its voxel's number.
    voxel_of: Vec<u32>,
    /// Dense: per voxel number, the sum of its points.
    sums: Vec<Sum>,
    /// Sorted: packed `(voxel key, point index)` words, sorted in place.
    words: Vec<u64>,
    /// Sorted: the radix sort's other buffer.
    scratch: Vec<u64>,
    /// Sorted: the radix sort's digit counts.
    counts: Vec<u32>,
    /// Definition: its answer.
    definition: Vec<[f32; 3]>,
    /// How the last grouping went, which says what the buffers hold.
    way: Way,
}

/// How [`VoxelGrid`] grouped the last cloud into voxels.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(super) enum Way {
    /// No points.
    #[default]
    Empty,
    /// A slot per voxel of the box; `voxels` of them occupied.
    Dense {
        /// Occupied voxels.
        voxels: usize,
    },
    /// The words sorted, the point index in their low `index_bits`.
    Sorted {
        /// Bits of the point index.
        index_bits: u32,
    },
    /// [`voxel_downsample`] itself (what neither way takes).
    Definition,
}

/// A voxel's points so far.
#[derive(Clone, Copy, Debug, Default)]
struct Sum {
    sum: [f64; 3],
    count: u32,
}

const EMPTY: u32 = u32::MAX;

/// Most voxels in the box for the dense way, beyond `2·n`: a slot is 4 bytes, written and read
/// once a call, so at most 8 bytes a point and 256 KiB.
const DENSE_SLACK: u64 = 1 << 16;

/// The least and greatest coordinates of a cloud, per axis, and whether one is NaN.
#[derive(Clone, Copy, Debug)]
struct Bounds {
    min: [f32; 3],
    max: [f32; 3],
    nan: bool,
}

/// The range of voxel indices of a cloud, per axis.
#[derive(Clone, Copy, Debug)]
struct CellBox {
    /// Least voxel index per axis.
    lo: [i64; 3],
    /// Greatest voxel index per axis.
    hi: [i64; 3],
}

/// How a cloud's voxel indices pack into a word: `key << index_bits | point index`.
#[derive(Clone, Copy, Debug)]
struct Packing {
    cells: CellBox,
    /// Left shift of each axis's relative index within the word.
    shift: [u32; 3],
    /// Bits of the point index (the low bits of the word).
    index_bits: u32,
    /// Bits of the key (above the point index).
    key_bits: u32,
}

impl VoxelGrid {
    /// An empty grid (buffers grow on first use).
    pub fn new() -> VoxelGrid {
        VoxelGrid::default()
    }

    /// One centroid per voxel of edge `voxel_m` of `points`, in `out` (cleared first).
    pub fn downsample(
        &mut self,
        points: &[[f32; 3]],
        voxel_m: f64,
        out: &mut Vec<[f32; 3]>,
    ) -> Result<(), VoxelError> {
        out.clear();
        self.group(points, &Bounds::of(points), voxel_m)?;
        self.emit(points, out);
        Ok(())
    }

    /// [`VoxelGrid::downsample`] at `voxel_m` (none: every point), then, while more than
    /// `max_points` remain, again at a coarser voxel (the edge grows by `√(n / max)`, a
    /// surface's points scaling with `1/edge²`, at least 10 %). Returns the edge used and whether
    /// the budget acted.
    ///
    /// A round needs only the number of voxels: the centroids are summed once, for the last.
    pub fn downsample_to_budget(
        &mut self,
        points: &[[f32; 3]],
        voxel_m: Option<f64>,
        max_points: usize,
        out: &mut Vec<[f32; 3]>,
    ) -> Result<(Option<f64>, bool), VoxelError> {
        out.clear();
        // The same points every round: their bounds once.
        let mut bounds = None;
        let mut bounds = || *bounds.get_or_insert_with(|| Bounds::of(points));
        let mut kept = match voxel_m {
            Some(v) => self.group(points, &bounds(), v)?,
            None => points.len(),
        };
        let max = max_points.max(1);
        let mut voxel = voxel_m;
        let mut acted = false;
        for _ in 0..16 {
            if kept <= max {
                break;
            }
            acted = true;
            let grow = (kept as f64 / max as f64).sqrt().max(1.1);
            let next = match voxel {
                Some(v) => v * grow,
                None => initial_voxel(points) * grow,
            };
            voxel = Some(next);
            // Coarsen from the original points: the centroids stay those of the points.
            kept = self.group(points, &bounds(), next)?;
        }
        match voxel {
            Some(_) => self.emit(points, out),
            None => out.extend_from_slice(points),
        }
        Ok((voxel, acted))
    }

    /// Groups `points` (within `bounds`) into voxels of edge `voxel_m`, for [`VoxelGrid::emit`];
    /// returns the number of voxels.
    fn group(
        &mut self,
        points: &[[f32; 3]],
        bounds: &Bounds,
        voxel_m: f64,
    ) -> Result<usize, VoxelError> {
        if !(voxel_m > 0.0 && voxel_m.is_finite()) {
            return Err(VoxelError::InvalidSize { value: voxel_m });
        }
        self.way = Way::Empty;
        if points.is_empty() {
            return Ok(0);
        }
        // Voxel numbers and radix counts are u32.
        let cells = CellBox::of(bounds, voxel_m).filter(|_| points.len() <= EMPTY as usize);
        let dense_limit = 2 * points.len() as u64 + DENSE_SLACK;
        let volume = cells.and_then(|c| c.volume()).filter(|&v| v <= dense_limit);
        let packing = cells.and_then(|c| Packing::new(c, points.len()));
        let voxels = match (cells, volume, packing) {
            (Some(cells), Some(volume), _) => {
                let voxels = self.assign(points, voxel_m, &cells, volume as usize);
                self.way = Way::Dense { voxels };
                voxels
            }
            (_, _, Some(packing)) => {
                self.words.clear();
                let words = points.iter().enumerate();
                self.words
                    .extend(words.map(|(i, p)| packing.word(i, p, voxel_m)));
                let (low, bits) = (packing.index_bits, packing.key_bits);
                radix::sort(
                    &mut self.words,
                    &mut self.scratch,
                    &mut self.counts,
                    low,
                    bits,
                );
                self.way = Way::Sorted { index_bits: low };
                let key = |w: u64| w >> low;
                1 + self
                    .words
                    .windows(2)
                    .filter(|w| key(w[0]) != key(w[1]))
                    .count()
            }
            _ => {
                // Set first, so that an error is seen to have come from here (no emit follows).
                self.way = Way::Definition;
                self.definition = voxel_downsample(points, voxel_m)?;
                self.definition.len()
            }
        };
        Ok(voxels)
    }

    /// The dense way's grouping: each point's voxel number, numbered in the order of first
    /// points, through a slot per voxel of `cells` (`volume` of them). Returns the count.
    fn assign(
        &mut self,
        points: &[[f32; 3]],
        voxel_m: f64,
        cells: &CellBox,
        volume: usize,
    ) -> usize {
        let [_, ny, nz] = cells.extent();
        self.slots.clear();
        self.slots.resize(volume, EMPTY);
        let slots = &mut self.slots;
        let mut voxels = 0u32;
        self.voxel_of.clear();
        self.voxel_of.extend(points.iter().map(|p| {
            let [i, j, k] = cells.relative(p, voxel_m);
            // Inside the box (i < nx, j < ny, k < nz), so always a slot.
            let Some(slot) = slots.get_mut((i * ny + j) * nz + k) else {
                return EMPTY;
            };
            // Written only for a new voxel: the next point, most often in the same voxel,
            // reads the slot without waiting for a store to it.
            if *slot == EMPTY {
                *slot = voxels;
                voxels += 1;
            }
            *slot
        }));
        voxels as usize
    }

    /// The centroids of the last grouping of `points`, in voxel index order, into `out`.
    fn emit(&mut self, points: &[[f32; 3]], out: &mut Vec<[f32; 3]>) {
        out.clear();
        match self.way {
            Way::Empty => {}
            Way::Dense { voxels } => {
                self.sums.clear();
                self.sums.resize(voxels, Sum::default());
                for (p, &v) in points.iter().zip(&self.voxel_of) {
                    if let Some(s) = self.sums.get_mut(v as usize) {
                        for (s, c) in s.sum.iter_mut().zip(p) {
                            *s += f64::from(*c);
                        }
                        s.count += 1;
                    }
                }
                let sums = &self.sums;
                out.extend(
                    self.slots
                        .iter()
                        .filter_map(|&v| sums.get(v as usize))
                        .map(|v| v.sum.map(|s| (s / f64::from(v.count)) as f32)),
                );
            }
            Way::Sorted { index_bits } => centroids(&self.words, index_bits, points, out),
            Way::Definition => out.extend_from_slice(&self.definition),
        }
    }

    /// How the last call grouped its cloud (to test each way).
    #[cfg(test)]
    pub(super) fn way(&self) -> Way {
        self.way
    }
}

impl Bounds {
    /// The bounds of `points`: four points (12 coordinates, three SSE registers) at a time,
    /// per lane, so that no comparison waits for the one before; lane `l` of the 12 holds axis
    /// `l mod 3`. Comparisons, not `f32::min`: one instruction each. A NaN never compares less
    /// or greater (so it is flagged instead).
    fn of(points: &[[f32; 3]]) -> Bounds {
        let mut min = [f32::INFINITY; 12];
        let mut max = [f32::NEG_INFINITY; 12];
        let mut nan = [false; 12];
        let flat = points.as_flattened();
        let (chunks, rest) = flat.split_at(flat.len() - flat.len() % 12);
        // The last points, padded with the first point's coordinates (of the same axes).
        let pad = |l: usize| rest.get(l).or(flat.get(l % 3)).copied().unwrap_or(0.0);
        let last: [f32; 12] = std::array::from_fn(pad);
        for chunk in chunks.chunks_exact(12).chain([last.as_slice()]) {
            for l in 0..12 {
                let c = chunk[l];
                nan[l] |= c.is_nan();
                min[l] = if c < min[l] { c } else { min[l] };
                max[l] = if c > max[l] { c } else { max[l] };
            }
        }
        let mut b = Bounds {
            min: [f32::INFINITY; 3],
            max: [f32::NEG_INFINITY; 3],
            nan: nan.contains(&true),
        };
        for l in 0..12 {
            b.min[l % 3] = if min[l] < b.min[l % 3] {
                min[l]
            } else {
                b.min[l % 3]
            };
            b.max[l % 3] = if max[l] > b.max[l % 3] {
                max[l]
            } else {
                b.max[l % 3]
            };
        }
        b
    }
}

impl CellBox {
    /// The voxel index range of points within `bounds` (of at least one point) at `voxel_m`, or
    /// `None` if a coordinate is NaN or an index is not below 2^51 in magnitude (an infinity
    /// among them).
    fn of(bounds: &Bounds, voxel_m: f64) -> Option<CellBox> {
        if bounds.nan {
            return None;
        }
        let mut cells = CellBox {
            lo: [0; 3],
            hi: [0; 3],
        };
        for k in 0..3 {
            cells.lo[k] = checked_cell(bounds.min[k], voxel_m)?;
            cells.hi[k] = checked_cell(bounds.max[k], voxel_m)?;
        }
        Some(cells)
    }

    /// Voxels per axis (below 2^52 each).
    fn extent(&self) -> [usize; 3] {
        std::array::from_fn(|k| (self.hi[k] - self.lo[k] + 1) as usize)
    }

    /// Voxels in the box, if below 2^64.
    fn volume(&self) -> Option<u64> {
        let [x, y, z] = self.extent().map(|e| e as u64);
        x.checked_mul(y)?.checked_mul(z)
    }

    /// The voxel index of `p` (inside the box) relative to the box's lowest.
    #[inline(always)]
    fn relative(&self, p: &[f32; 3], voxel_m: f64) -> [usize; 3] {
        std::array::from_fn(|k| {
            let c = cell(p[k], voxel_m);
            debug_assert!(
                (self.lo[k]..=self.hi[k]).contains(&c),
                "{p:?} outside the box"
            );
            (c - self.lo[k]) as usize
        })
    }
}

impl Packing {
    /// The packing of `n` points in `cells`, or `None` if key and index need more than 64 bits.
    fn new(cells: CellBox, n: usize) -> Option<Packing> {
        let bits = cells
            .extent()
            .map(|e| usize::BITS - (e - 1).leading_zeros());
        let index_bits = usize::BITS - n.saturating_sub(1).leading_zeros();
        let key_bits = bits[0] + bits[1] + bits[2];
        if index_bits + key_bits > u64::BITS {
            return None;
        }
        // An axis of one voxel has no bits (and a shift that may be 64: not used).
        let at = |s: u32, b: u32| if b == 0 { 0 } else { s };
        Some(Packing {
            cells,
            shift: [
                at(index_bits + bits[1] + bits[2], bits[0]),
                at(index_bits + bits[2], bits[1]),
                at(index_bits, bits[2]),
            ],
            index_bits,
            key_bits,
        })
    }

    /// The word of point `index`, `p` (inside the box).
    #[inline(always)]
    fn word(&self, index: usize, p: &[f32; 3], voxel_m: f64) -> u64 {
        let rel = self.cells.relative(p, voxel_m);
        let mut word = index as u64;
        for (r, s) in rel.into_iter().zip(self.shift) {
            word |= (r as u64) << s;
        }
        word
    }
}

/// `⌊c / voxel_m⌋`, the quotient rounded as [`voxel_downsample`] rounds it, for `|c / voxel_m|`
/// below 2^51 (`checked_cell` checks that).
#[inline(always)]
fn cell(c: f32, voxel_m: f64) -> i64 {
    floor(f64::from(c) / voxel_m)
}

/// `⌊q⌋` for `|q|` < 2^51, without the libm call the baseline x86-64 target makes for
/// `f64::floor` (SSE2 has no rounding instruction) or the range checks of a saturating `as`.
/// Adding 1.5 · 2^52 rounds `q` to an integer `n` (every f64 in [2^52, 2^53) is one, and
/// consecutive integers have consecutive bit patterns there, so `n` is read from the bits);
/// `n − 1` where that rounded up.
#[inline(always)]
fn floor(q: f64) -> i64 {
    const MAGIC: f64 = 6_755_399_441_055_744.0; // 1.5 · 2^52
    let r = q + MAGIC;
    let n = r.to_bits() as i64 - MAGIC.to_bits() as i64;
    n - i64::from(r - MAGIC > q)
}

/// [`cell`], or `None` if the quotient is not finite or not below 2^51 in magnitude.
fn checked_cell(c: f32, voxel_m: f64) -> Option<i64> {
    const LIMIT: f64 = 2_251_799_813_685_248.0; // 2^51
    let q = f64::from(c) / voxel_m;
    (q.abs() < LIMIT).then(|| cell(c, voxel_m))
}

/// The centroid of each run of equal keys of the sorted `words`, in order, appended to `out`.
fn centroids(words: &[u64], index_bits: u32, points: &[[f32; 3]], out: &mut Vec<[f32; 3]>) {
    let index_mask = u64::MAX.checked_shr(u64::BITS - index_bits).unwrap_or(0);
    let mut rest = words;
    while let Some(&first) = rest.first() {
        let key = first & !index_mask;
        let mut sum = [0.0f64; 3];
        let mut len = 0usize;
        for &w in rest.iter().take_while(|&&w| w & !index_mask == key) {
            let p = points[(w & index_mask) as usize];
            for k in 0..3 {
                sum[k] += f64::from(p[k]);
            }
            len += 1;
        }
        out.push(sum.map(|s| (s / len as f64) as f32));
        rest = &rest[len..];
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn floor_is_f64_floor_below_2_pow_51() {
        let limit = 2_251_799_813_685_248.0f64; // 2^51
        let mut qs = vec![0.0, -0.0, 0.5, -0.5, 1.5, -1.5, 2.5, -2.5, 1e-300, -1e-300];
        for m in [
            1.0,
            3.0,
            1e6,
            4_503_599_627_370_495.0 / 2.0,
            limit / 2.0,
            limit,
        ] {
            for q in [m, -m] {
                qs.extend([q, q.next_up(), q.next_down(), q + 0.5, q - 0.5]);
            }
        }
        for q in qs.into_iter().filter(|q: &f64| q.abs() < limit) {
            assert_eq!(floor(q), q.floor() as i64, "{q:e}");
        }
    }
}

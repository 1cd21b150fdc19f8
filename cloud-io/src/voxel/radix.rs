//! The sorted way's radix sort: stable, least significant digit first, on `u64` words.

/// Widest radix digit: 4,096 counters (16 KiB) per stream stay in the L1 cache.
const MAX_DIGIT_BITS: u32 = 12;

/// Sorts `words` by their bits `low .. low + bits` (`low + bits` ≤ 64), stably, with `scratch`
/// and `counts` as working space: as few passes of at most [`MAX_DIGIT_BITS`] bits as the key
/// needs, the digits equally wide.
pub(super) fn sort(
    words: &mut Vec<u64>,
    scratch: &mut Vec<u64>,
    counts: &mut Vec<u32>,
    low: u32,
    bits: u32,
) {
    let passes = bits.div_ceil(MAX_DIGIT_BITS);
    if passes == 0 {
        return;
    }
    let width = bits.div_ceil(passes);
    scratch.clear();
    scratch.resize(words.len(), 0);
    for pass in 0..passes {
        // Below 64: (passes − 1) · width < bits ≤ 64 − low.
        let digit = Digit {
            shift: low + pass * width,
            mask: (1 << width) - 1,
        };
        if counting_pass(words, scratch, counts, digit) {
            std::mem::swap(words, scratch);
        }
    }
}

/// One radix digit of a word: `(word >> shift) & mask`.
#[derive(Clone, Copy, Debug)]
struct Digit {
    shift: u32,
    mask: u64,
}

impl Digit {
    #[inline(always)]
    fn of(self, word: u64) -> usize {
        ((word >> self.shift) & self.mask) as usize
    }
}

/// Words a counting pass reads in step: a camera's consecutive points share their low digits,
/// so one stream would increment the same counter back to back, each increment waiting for the
/// last; four streams (the quarters of the words, each with counters of its own) keep four
/// increments in flight.
const STREAMS: usize = 4;

/// Moves `src` into `dst` ordered by `digit`, stably, and returns true; or returns false (and
/// leaves `dst` as it was) if every word has the same digit.
fn counting_pass(src: &[u64], dst: &mut [u64], counts: &mut Vec<u32>, digit: Digit) -> bool {
    let buckets = digit.mask as usize + 1;
    let quarter = src.len().div_ceil(STREAMS);
    let streams: [&[u64]; STREAMS] = std::array::from_fn(|s| {
        let start = (s * quarter).min(src.len());
        &src[start..(start + quarter).min(src.len())]
    });
    // Counts a u32: `src` holds at most 2^32 − 1 words (`VoxelGrid::group` sorts no more).
    counts.clear();
    counts.resize(STREAMS * buckets, 0);
    in_step(streams, |s, w| counts[s * buckets + digit.of(w)] += 1);
    // Stream s's words of digit d go after every word of a smaller digit and after stream
    // s − 1's words of digit d: the order within a digit stays the input order.
    let mut start = 0u32;
    for d in 0..buckets {
        let total: u32 = (0..STREAMS).map(|s| counts[s * buckets + d]).sum();
        if total as usize == src.len() {
            return false;
        }
        for s in 0..STREAMS {
            let c = &mut counts[s * buckets + d];
            (*c, start) = (start, start + *c);
        }
    }
    in_step(streams, |s, w| {
        let slot = &mut counts[s * buckets + digit.of(w)];
        dst[*slot as usize] = w;
        *slot += 1;
    });
    true
}

/// Calls `f(s, word)` for every word of every stream, in order within a stream, the streams
/// in turn word by word.
#[inline(always)]
fn in_step(streams: [&[u64]; STREAMS], mut f: impl FnMut(usize, u64)) {
    let len = streams[0].len();
    for i in 0..len {
        for (s, stream) in streams.iter().enumerate() {
            if let Some(&w) = stream.get(i) {
                f(s, w);
            }
        }
    }
}

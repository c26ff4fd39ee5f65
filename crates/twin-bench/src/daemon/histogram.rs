//! A latency histogram of fixed size: every value is counted (no sampling),
//! with a relative resolution better than 1 %, in memory allocated once
//! before a measurement starts (so that recording does not move the
//! process's RSS, which the benchmark also reports).
//!
//! Values are nanoseconds. Below 128 ns each value has its own bucket; above,
//! each power of two is split into 128 equal buckets, so a bucket is at most
//! 1/128 of its lower bound wide. The exact minimum and maximum are kept
//! beside the buckets.

/// Sub-buckets per power of two (and the exact range below it).
const SUB: u64 = 128;
/// log2 of [`SUB`].
const SUB_BITS: u32 = 7;
/// Buckets for every `u64`.
const BUCKETS: usize = ((64 - SUB_BITS as usize) + 1) * SUB as usize;

/// Counts of values in log-linear buckets.
#[derive(Debug, Clone)]
pub struct Histogram {
    counts: Vec<u64>,
    total: u64,
    min: u64,
    max: u64,
    sum: u128,
}

impl Default for Histogram {
    fn default() -> Self {
        Self::new()
    }
}

fn index(v: u64) -> usize {
    if v < SUB {
        return v as usize;
    }
    // The highest set bit is at `top` >= SUB_BITS; the SUB_BITS bits below
    // it pick the sub-bucket.
    let top = 63 - v.leading_zeros();
    let shift = top - SUB_BITS;
    let sub = (v >> shift) & (SUB - 1);
    ((shift as usize + 1) << SUB_BITS) + sub as usize
}

/// The lowest value of bucket `i` and its width.
fn bounds(i: usize) -> (u64, u64) {
    if (i as u64) < SUB {
        return (i as u64, 1);
    }
    let shift = (i >> SUB_BITS) as u32 - 1;
    let sub = (i as u64) & (SUB - 1);
    let low = (SUB + sub) << shift;
    (low, 1u64 << shift)
}

impl Histogram {
    /// An empty histogram (about 60 KB, allocated and written here).
    pub fn new() -> Self {
        Self {
            counts: vec![0; BUCKETS],
            total: 0,
            min: u64::MAX,
            max: 0,
            sum: 0,
        }
    }

    /// Counts one value.
    pub fn record(&mut self, v: u64) {
        self.counts[index(v)] += 1;
        self.total += 1;
        self.min = self.min.min(v);
        self.max = self.max.max(v);
        self.sum += u128::from(v);
    }

    /// Values counted.
    pub fn count(&self) -> u64 {
        self.total
    }

    /// The smallest value, exactly (`None` when empty).
    pub fn min(&self) -> Option<u64> {
        (self.total > 0).then_some(self.min)
    }

    /// The largest value, exactly (`None` when empty).
    pub fn max(&self) -> Option<u64> {
        (self.total > 0).then_some(self.max)
    }

    /// The mean (`None` when empty).
    pub fn mean(&self) -> Option<f64> {
        (self.total > 0).then(|| self.sum as f64 / self.total as f64)
    }

    /// The `q` quantile (0 < q <= 1): the middle of the bucket holding the
    /// value of rank `ceil(q n)`, clamped to the exact minimum and maximum.
    /// `None` when empty.
    pub fn quantile(&self, q: f64) -> Option<u64> {
        if self.total == 0 {
            return None;
        }
        let rank = ((q.clamp(0.0, 1.0) * self.total as f64).ceil() as u64).max(1);
        let mut seen = 0;
        for (i, &c) in self.counts.iter().enumerate() {
            seen += c;
            if seen >= rank {
                let (low, width) = bounds(i);
                let mid = low + width / 2;
                return Some(mid.clamp(self.min, self.max));
            }
        }
        Some(self.max)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn buckets_cover_every_value_in_order() {
        let mut last = 0;
        for v in (0..5000u64).chain([1 << 20, (1 << 20) + 1, u64::MAX / 3, u64::MAX]) {
            let i = index(v);
            assert!(i < BUCKETS, "{v}");
            assert!(i >= last, "{v}");
            last = i;
            let (low, width) = bounds(i);
            assert!(
                low <= v && v - low < width,
                "{v}: bucket {i} = [{low}, +{width})"
            );
            // Relative width under 1 %.
            if v >= SUB {
                assert!((width as f64) / (low as f64) <= 1.0 / SUB as f64 + 1e-12);
            }
        }
    }

    #[test]
    fn quantiles_are_within_a_percent() {
        let mut h = Histogram::new();
        assert_eq!(h.quantile(0.5), None);
        // 1..=100_000 ns: p50 = 50_000, p99 = 99_000.
        for v in 1..=100_000u64 {
            h.record(v);
        }
        assert_eq!(h.count(), 100_000);
        assert_eq!(h.min(), Some(1));
        assert_eq!(h.max(), Some(100_000));
        for (q, want) in [(0.5, 50_000.0), (0.99, 99_000.0), (1.0, 100_000.0)] {
            let got = h.quantile(q).unwrap() as f64;
            assert!((got - want).abs() / want < 0.01, "q {q}: {got} vs {want}");
        }
        assert!((h.mean().unwrap() - 50_000.5).abs() < 1e-6);
    }
}

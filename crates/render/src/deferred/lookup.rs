//! Which instance draws a global triangle ID: a search over the instances in first-triangle
//! order (guessing positions by interpolation in long lists), tried after the last answer
//! and its neighbours.

use std::sync::OnceLock;

use sightline_scene::Instance;

/// Above this many positions left, [`Lookup`]'s search guesses where to probe.
const INTERPOLATE_ABOVE: usize = 1024;

/// Finds the instance drawing global triangle `g`. Instances come ordered by first triangle
/// (as [`Scene::instances`](sightline_scene::Scene::instances) lists them), and a search over them answers; only when
/// it finds no instance is the order checked, and for an unordered list a sorted index
/// made, once (checking up front read every instance record each frame: 8.5 MB and about
/// 0.4 ms for the 53,000 instances of a 10^9-triangle city).
pub(crate) struct Lookup<'a> {
    pub(crate) instances: &'a [Instance],
    /// The instances with triangles in first-triangle order, when the list is not in it.
    order: OnceLock<Option<Vec<u32>>>,
    /// Instance records the searches have read (tests count the guesses' probes).
    #[cfg(test)]
    pub(crate) probes: std::sync::atomic::AtomicUsize,
}

impl<'a> Lookup<'a> {
    pub(crate) fn new(instances: &'a [Instance]) -> Self {
        Self {
            instances,
            order: OnceLock::new(),
            #[cfg(test)]
            probes: Default::default(),
        }
    }

    /// The instance drawing global triangle `g`, trying `hint` (the last answer) and the
    /// three instances after it (or before it, when `g` comes before the hint's range) first:
    /// neighboring pixels mostly show the same instance or a sibling, and in a list in
    /// first-triangle order the owner lies on `g`'s side of the hint. In the street view of a
    /// 10^9-triangle city this leaves one search in six.
    #[inline]
    pub(crate) fn find_hinted(&self, g: u32, hint: &mut u32) -> Option<u32> {
        let holds = |k: u32| {
            self.instances
                .get(k as usize)
                .is_some_and(|i| g >= i.first_triangle && g - i.first_triangle < i.triangle_count)
        };
        // A building's walls, dark panes and lit panes are three instances in a row, and a
        // distant facade's pixels alternate between them.
        if holds(*hint) {
            return Some(*hint);
        }
        let after = self.instances.get(*hint as usize).is_none_or(|i| g >= i.first_triangle);
        for d in 1..=3u32 {
            let k = if after { hint.wrapping_add(d) } else { hint.wrapping_sub(d) };
            if holds(k) {
                *hint = k;
                return Some(k);
            }
        }
        let i = self.find(g)?;
        *hint = i;
        Some(i)
    }

    pub(crate) fn find(&self, g: u32) -> Option<u32> {
        let n = self.instances.len();
        // Instance ranges do not overlap: whatever the order, an instance found holding `g`
        // is the answer.
        if let Some(i) = self.search(g, n, |k| k as u32) {
            return Some(i);
        }
        let order = self.order.get_or_init(|| {
            let sorted = self.instances.windows(2).all(|w| w[0].first_triangle <= w[1].first_triangle);
            (!sorted).then(|| {
                let mut o: Vec<u32> =
                    (0..n as u32).filter(|&i| self.instances[i as usize].triangle_count > 0).collect();
                o.sort_by_key(|&i| self.instances[i as usize].first_triangle);
                o
            })
        });
        let o = order.as_ref()?;
        self.search(g, o.len(), |k| o[k])
    }

    /// Search for `g` over the `n` instances `inst(0..n)`, taken to be in first-triangle
    /// order. While more than [`INTERPOLATE_ABOVE`] positions remain, a probe guesses the
    /// position by interpolating between the first triangles known at the interval's ends
    /// (Perl, Itai, Avni, "Interpolation Search — A Log Log N Search", CACM 1978), and one
    /// that left more than half the interval is followed by a halving one, so no search
    /// takes much more than twice a binary search's probes; the last positions are halved.
    /// A probe of a large list reads an instance record from memory: on the boxfield's
    /// 83,334 instances of twelve triangles each a binary search made 16.4 probes, the
    /// guesses 2.5, and a search took about a quarter of the time; on the default city's
    /// 1,897 instances of many sizes, whose records stay in cache, a guess costs more than
    /// it saves below about a thousand positions.
    fn search(&self, g: u32, n: usize, inst: impl Fn(usize) -> u32) -> Option<u32> {
        let first = |k: usize| {
            #[cfg(test)]
            self.probes.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            self.instances[inst(k) as usize].first_triangle
        };
        // The number of positions whose first triangle is ≤ g, in `lo..=hi`; `below` is a
        // first triangle ≤ g at or before `lo` (0 at the start) and `above` one past g at or
        // after `hi` (at the start, where the last instance ends). In an unordered list
        // (searched once before its index is made) either may not hold: then the probe halves.
        let (mut lo, mut hi) = (0, n);
        let mut below = 0u32;
        let mut above = n.checked_sub(1).map_or(0, |k| {
            let last = &self.instances[inst(k) as usize];
            last.first_triangle.saturating_add(last.triangle_count)
        });
        let mut halve = false;
        while lo < hi {
            let width = hi - lo;
            let mid = if halve || width <= INTERPOLATE_ABOVE || g >= above || g < below {
                lo + width / 2
            } else {
                // In f64 (exact for these integers, and a shorter division than u64's); the
                // guess is only where to probe, so its rounding cannot change the answer.
                let guess = (g - below) as f64 * width as f64 / (above - below) as f64;
                lo + (guess as usize).min(width - 1)
            };
            let f = first(mid);
            if f <= g {
                (lo, below) = (mid + 1, f);
            } else {
                (hi, above) = (mid, f);
            }
            halve = !halve && 2 * (hi - lo) > width;
        }
        // The last position whose first triangle is ≤ g, stepping back over empty instances.
        let mut k = lo;
        while k > 0 {
            k -= 1;
            let i = inst(k);
            let it = &self.instances[i as usize];
            if g < it.first_triangle {
                return None;
            }
            if g - it.first_triangle < it.triangle_count {
                return Some(i);
            }
            if it.triangle_count > 0 {
                return None;
            }
        }
        None
    }
}

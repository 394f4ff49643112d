//! The identifier's preallocated rings of samples and commands, and the
//! cursor that finds the command in force at each sample.

/// A fixed-capacity ring of time-stamped values, oldest overwritten.
#[derive(Debug, Clone)]
pub(crate) struct Ring<const N: usize> {
    stamp: Vec<u64>,
    values: Vec<[f64; N]>,
    flags: Vec<u32>,
    head: usize,
    len: usize,
}

impl<const N: usize> Ring<N> {
    pub(crate) fn new(capacity: usize) -> Self {
        Ring {
            stamp: vec![0; capacity],
            values: vec![[0.0; N]; capacity],
            flags: vec![0; capacity],
            head: 0,
            len: 0,
        }
    }

    /// Allocation-free.
    pub(crate) fn push(&mut self, stamp: u64, v: [f64; N], flags: u32) {
        let cap = self.stamp.len();
        let i = (self.head + self.len) % cap;
        self.stamp[i] = stamp;
        self.values[i] = v;
        self.flags[i] = flags;
        if self.len < cap {
            self.len += 1;
        } else {
            self.head = (self.head + 1) % cap;
        }
    }

    /// The `k`-th entry, oldest first.
    pub(crate) fn get(&self, k: usize) -> (u64, [f64; N], u32) {
        let i = (self.head + k) % self.stamp.len();
        (self.stamp[i], self.values[i], self.flags[i])
    }

    /// Entries with `start <= stamp < end`, oldest first (no allocation).
    pub(crate) fn window(
        &self,
        start: u64,
        end: u64,
    ) -> impl Iterator<Item = (u64, [f64; N], u32)> + '_ {
        (0..self.len)
            .map(|k| self.get(k))
            .filter(move |(s, _, _)| *s >= start && *s < end)
    }

    pub(crate) fn latest(&self) -> Option<u64> {
        (self.len > 0).then(|| self.get(self.len - 1).0)
    }
}

/// Walks the command ring alongside increasing sample stamps: the command
/// in force at a sample is the latest one stamped at or before it (the
/// controller stamps each command with the stamp of the sample it answers).
pub(crate) struct CommandCursor<'a> {
    ring: &'a Ring<2>,
    next: usize,
    current: Option<(u64, [f64; 2])>,
}

impl<'a> CommandCursor<'a> {
    pub(crate) fn new(ring: &'a Ring<2>) -> Self {
        CommandCursor {
            ring,
            next: 0,
            current: None,
        }
    }

    /// `([τ_d, τ_gravity], exact)` in force at `stamp`; `exact` when the
    /// command answers this very sample.
    pub(crate) fn at(&mut self, stamp: u64) -> Option<([f64; 2], bool)> {
        while self.next < self.ring.len {
            let (s, v, _) = self.ring.get(self.next);
            if s > stamp {
                break;
            }
            self.current = Some((s, v));
            self.next += 1;
        }
        self.current.map(|(s, v)| (v, s == stamp))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A window is half-open, `start <= stamp < end` (the analysis window's
    /// closing state belongs to the next window, not to this one), oldest
    /// first, also after the ring has wrapped.
    #[test]
    fn a_window_holds_its_start_and_not_its_end() {
        for (cap, pushes) in [(16, 6u64), (4, 6)] {
            let mut ring = Ring::<1>::new(cap);
            for i in 1..=pushes {
                ring.push(10 * i, [i as f64], 0);
            }
            let stamps = |a: u64, b: u64| ring.window(a, b).map(|e| e.0).collect::<Vec<_>>();
            assert_eq!(stamps(30, 50), vec![30, 40], "ring of {cap}");
            assert_eq!(stamps(31, 60), vec![40, 50], "ring of {cap}");
            assert_eq!(stamps(40, 40), Vec::<u64>::new());
            assert_eq!(stamps(50, 61), vec![50, 60]);
        }
    }

    #[test]
    fn the_command_cursor_gives_the_latest_command_at_or_before_a_stamp() {
        // A ring with room to spare, and a full one that has wrapped.
        for (cap, pushes) in [(8, 2), (3, 5)] {
            let mut ring = Ring::<2>::new(cap);
            for i in 1..=pushes {
                ring.push(10 * i, [i as f64, -(i as f64)], 0);
            }
            let oldest = 10 * (pushes - ring.len as u64 + 1);
            let newest = 10 * pushes;
            let mut c = CommandCursor::new(&ring);
            assert_eq!(c.at(oldest - 5), None, "before every command");
            let v = |s: u64| [(s / 10) as f64, -((s / 10) as f64)];
            assert_eq!(c.at(oldest), Some((v(oldest), true)));
            assert_eq!(c.at(oldest + 5), Some((v(oldest), false)));
            assert_eq!(c.at(newest), Some((v(newest), true)));
            // Past the last command: still the last one, not an unwritten
            // or overwritten slot of the ring.
            assert_eq!(c.at(newest + 5), Some((v(newest), false)));
            assert_eq!(c.at(newest + 50), Some((v(newest), false)));
        }
    }
}

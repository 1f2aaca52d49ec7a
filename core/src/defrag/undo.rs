//! First-old-value logs: every slot of an engine table that a merge attempt writes is saved once,
//! before its first write, so a rejected attempt is undone in time proportional to what it
//! touched (never to the size of the charts), and the checks can read the state before the merge.

use crate::index::NONE;

/// The saved first values of the slots of one table written during an attempt.
#[derive(Debug)]
pub(crate) struct Saved<T: Copy> {
    /// Slot → index into `items`, or `NONE` when the slot was not written.
    index: Vec<u32>,
    items: Vec<(u32, T)>,
}

impl<T: Copy> Saved<T> {
    /// A log for a table of `n` slots.
    pub fn new(n: usize) -> Self {
        Self { index: vec![NONE; n], items: Vec::new() }
    }

    /// Writes `value` into `table[slot]`, saving the old value if this is the slot's first write.
    #[inline]
    pub fn set(&mut self, table: &mut [T], slot: usize, value: T) {
        if self.index[slot] == NONE {
            self.index[slot] = self.items.len() as u32;
            self.items.push((slot as u32, table[slot]));
        }
        table[slot] = value;
    }

    /// The value `slot` had before the attempt, if it was written since.
    #[inline]
    pub fn old(&self, slot: usize) -> Option<T> {
        match self.index[slot] {
            NONE => None,
            i => Some(self.items[i as usize].1),
        }
    }

    /// The value `slot` had before the attempt.
    #[inline]
    pub fn before(&self, table: &[T], slot: usize) -> T {
        self.old(slot).unwrap_or(table[slot])
    }

    /// Restores every written slot and forgets the log.
    pub fn restore(&mut self, table: &mut [T]) {
        for &(slot, old) in &self.items {
            table[slot as usize] = old;
            self.index[slot as usize] = NONE;
        }
        self.items.clear();
    }

    /// Keeps the new values and forgets the log.
    pub fn commit(&mut self) {
        for &(slot, _) in &self.items {
            self.index[slot as usize] = NONE;
        }
        self.items.clear();
    }

    /// The written slots, in order of first write.
    pub fn slots(&self) -> impl Iterator<Item = u32> + '_ {
        self.items.iter().map(|&(s, _)| s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn restore_brings_back_first_values_and_before_reads_them() {
        let mut t = vec![1, 2, 3, 4];
        let mut log = Saved::new(t.len());
        log.set(&mut t, 1, 20);
        log.set(&mut t, 1, 200);
        log.set(&mut t, 3, 40);
        assert_eq!(t, [1, 200, 3, 40]);
        assert_eq!(log.before(&t, 1), 2);
        assert_eq!(log.before(&t, 0), 1);
        assert_eq!(log.slots().count(), 2);
        log.restore(&mut t);
        assert_eq!(t, [1, 2, 3, 4]);
        assert_eq!(log.old(1), None);
        log.set(&mut t, 0, 9);
        log.commit();
        assert_eq!(t, [9, 2, 3, 4]);
        assert_eq!(log.slots().count(), 0);
    }
}

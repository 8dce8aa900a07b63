//! The mock's record of rendered forces: a fixed-capacity ring that overwrites its oldest entry
//! when full and never grows after construction, so recording is allocation-free on the RT path.

use std::io::{self, BufWriter, Write};
use std::iter::{Chain, Copied};
use std::path::Path;
use std::slice;

/// Default ring capacity: 2 minutes at 1 kHz.
pub const FORCE_RECORD_CAPACITY: usize = 120_000;

/// One recorded force: run time of the read before it (seconds), force (N, device frame).
pub type ForceEntry = (f64, [f64; 3]);

/// The force ring: the mock's and the hand's record of rendered forces.
pub(crate) type ForceRing = Ring<ForceEntry>;

/// Owner of a ring's storage (inside a device).
#[derive(Debug)]
pub(crate) struct Ring<T> {
    /// Allocated once in `with_capacity`; a boxed slice so it cannot grow.
    entries: Box<[T]>,
    /// Index the next push writes; when the ring is full it is also the oldest entry.
    next: usize,
    /// Entries held, `<= entries.len()`.
    len: usize,
    /// Entries ever pushed.
    total: u64,
}

impl<T: Copy + Default> Ring<T> {
    /// A ring holding the last `capacity` entries (at least 1).
    pub(crate) fn with_capacity(capacity: usize) -> Self {
        Self {
            entries: vec![T::default(); capacity.max(1)].into_boxed_slice(),
            next: 0,
            len: 0,
            total: 0,
        }
    }

    /// Appends an entry, overwriting the oldest when full. Allocation-free.
    pub(crate) fn push_entry(&mut self, entry: T) {
        let capacity = self.entries.len();
        self.entries[self.next] = entry;
        self.next = (self.next + 1) % capacity;
        self.len = (self.len + 1).min(capacity);
        self.total += 1;
    }

    /// The held entries in time order: the older part, then the newer.
    pub(crate) fn parts(&self) -> (&[T], &[T]) {
        if self.len < self.entries.len() {
            (&self.entries[..self.len], &self.entries[..0])
        } else {
            (&self.entries[self.next..], &self.entries[..self.next])
        }
    }
}

impl ForceRing {
    /// Appends a force rendered at `t`. Allocation-free.
    pub(crate) fn push(&mut self, t: f64, force_n: [f64; 3]) {
        self.push_entry((t, force_n));
    }

    /// A read-only view in time order.
    pub(crate) fn view(&self) -> ForceRecord<'_> {
        let (older, newer) = self.parts();
        ForceRecord {
            older,
            newer,
            total: self.total,
            capacity: self.entries.len(),
        }
    }
}

/// The forces a mock device rendered, oldest to newest (a borrowed view of its ring).
#[derive(Clone, Copy, Debug)]
pub struct ForceRecord<'a> {
    /// The older part of the ring (from the oldest entry to the end of storage).
    older: &'a [ForceEntry],
    /// The newer part (from the start of storage to the newest entry); empty until wrap-around.
    newer: &'a [ForceEntry],
    total: u64,
    capacity: usize,
}

impl<'a> ForceRecord<'a> {
    /// The held entries, oldest first.
    pub fn iter(&self) -> ForceRecordIter<'a> {
        self.older.iter().chain(self.newer).copied()
    }

    /// Entries held (at most [`capacity`](Self::capacity)).
    pub fn len(&self) -> usize {
        self.older.len() + self.newer.len()
    }

    /// Whether nothing has been recorded.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// How many entries the ring holds before it overwrites the oldest.
    pub fn capacity(&self) -> usize {
        self.capacity
    }

    /// Entries ever recorded, including those overwritten: every `write_force` that reached the
    /// device, plus the zero written by `stop`.
    pub fn total_writes(&self) -> u64 {
        self.total
    }

    /// The newest entry.
    pub fn last(&self) -> Option<ForceEntry> {
        self.newer.last().or(self.older.last()).copied()
    }
}

/// Iterator over a [`ForceRecord`], oldest first (double-ended: `.rev()` is newest first).
pub type ForceRecordIter<'a> =
    Copied<Chain<slice::Iter<'a, ForceEntry>, slice::Iter<'a, ForceEntry>>>;

impl<'a> IntoIterator for ForceRecord<'a> {
    type Item = ForceEntry;
    type IntoIter = ForceRecordIter<'a>;

    fn into_iter(self) -> Self::IntoIter {
        self.iter()
    }
}

/// Writes `record` as CSV: a `t,fx,fy,fz` header, then one row per entry, oldest first, in
/// seconds and newtons.
pub(crate) fn write_force_csv(record: ForceRecord<'_>, path: &Path) -> io::Result<()> {
    write_force_csv_with(record, None, path)
}

/// [`write_force_csv`] with one more column, `name`, whose values (one per entry, oldest
/// first) come from `extra`.
pub(crate) fn write_force_csv_with(
    record: ForceRecord<'_>,
    extra: Option<(&str, &Ring<f64>)>,
    path: &Path,
) -> io::Result<()> {
    let mut out = BufWriter::new(std::fs::File::create(path)?);
    match extra {
        None => writeln!(out, "t,fx,fy,fz")?,
        Some((name, _)) => writeln!(out, "t,fx,fy,fz,{name}")?,
    }
    let values = extra.map(|(_, ring)| {
        let (older, newer) = ring.parts();
        older.iter().chain(newer).copied()
    });
    let mut values = values.into_iter().flatten();
    for (t, [fx, fy, fz]) in record {
        match extra {
            None => writeln!(out, "{t},{fx},{fy},{fz}")?,
            Some(_) => {
                let v = values.next().unwrap_or(f64::NAN);
                writeln!(out, "{t},{fx},{fy},{fz},{v}")?
            }
        }
    }
    out.flush()
}

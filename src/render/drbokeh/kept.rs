//! Tables a process keeps between renders: the last few made, each with the key it was made
//! from. A session refocusing, the frames of a shot and the renders of a benchmark go through
//! one aperture, and some of its tables cost as much as the GPU's whole render of a frame.
use std::sync::{Arc, Mutex};

/// The last [`KeptTables::KEPT`] tables asked for, the most recently used last.
pub(crate) struct KeptTables<K, V: ?Sized> {
    tables: Mutex<Vec<(K, Arc<V>)>>,
}

impl<K: PartialEq, V: ?Sized> KeptTables<K, V> {
    /// Tables kept: a few apertures; each table is a few KB.
    const KEPT: usize = 4;

    pub(crate) const fn new() -> Self {
        Self { tables: Mutex::new(Vec::new()) }
    }

    /// The table made from `key`: a kept one, else `make()`'s (made without the lock, so
    /// renders through other keys do not wait for it), then kept.
    pub(crate) fn get_or_make(&self, key: K, make: impl FnOnce() -> Arc<V>) -> Arc<V> {
        let found = |tables: &mut Vec<(K, Arc<V>)>| {
            let i = tables.iter().position(|(kept, _)| *kept == key)?;
            let entry = tables.remove(i);
            let table = entry.1.clone();
            tables.push(entry);
            Some(table)
        };
        if let Some(table) = found(&mut self.lock()) {
            return table;
        }
        let table = make();
        let mut tables = self.lock();
        if let Some(kept) = found(&mut tables) {
            return kept; // made meanwhile by another render
        }
        if tables.len() == Self::KEPT {
            tables.remove(0);
        }
        tables.push((key, table.clone()));
        table
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, Vec<(K, Arc<V>)>> {
        self.tables.lock().unwrap_or_else(|e| e.into_inner())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keeps_the_most_recently_used_tables() {
        let kept: KeptTables<u32, u32> = KeptTables::new();
        let made = std::cell::Cell::new(0);
        let get = |key: u32| {
            *kept.get_or_make(key, || {
                made.set(made.get() + 1);
                Arc::new(key * 10)
            })
        };
        for key in [1, 2, 3, 4] {
            assert_eq!(get(key), key * 10);
        }
        assert_eq!(made.get(), 4);
        assert_eq!(get(1), 10); // kept, now the most recent
        assert_eq!(get(5), 50); // pushes out 2, the least recent
        assert_eq!(made.get(), 5);
        assert_eq!((get(1), get(3), get(4), get(5)), (10, 30, 40, 50));
        assert_eq!(made.get(), 5);
        assert_eq!(get(2), 20);
        assert_eq!(made.get(), 6);
    }
}

//! The live lease table: deadlines are kept in memory (heartbeats never touch the
//! database) and rebuilt from the running attempts when the coordinator starts.

use crate::sched;
use gaitsweep_core::{CellId, LeaseId, SweepId, WorkerId};
use std::collections::{HashMap, HashSet};
use std::sync::Mutex;

/// What a heartbeat found for one lease.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Beat {
    /// Renewed until this deadline (unix ms).
    Active(i64),
    /// Unknown or expired: the worker must stop.
    Lost,
    /// The sweep was cancelled: the worker must stop.
    Cancelled,
}

#[derive(Debug, Clone)]
struct Entry {
    cell: CellId,
    sweep: SweepId,
    worker: WorkerId,
    deadline_ms: i64,
    cancelled: bool,
}

/// Live leases keyed by id.
#[derive(Debug, Default)]
pub struct LeaseTable {
    inner: Mutex<Inner>,
}

#[derive(Debug, Default)]
struct Inner {
    leases: HashMap<LeaseId, Entry>,
    seen: HashSet<WorkerId>,
}

impl LeaseTable {
    /// Adds a lease with its first deadline.
    pub fn insert(
        &self,
        lease: LeaseId,
        cell: CellId,
        sweep: SweepId,
        worker: WorkerId,
        deadline_ms: i64,
    ) {
        let mut g = self.inner.lock().expect("lease table poisoned");
        g.leases.insert(
            lease,
            Entry {
                cell,
                sweep,
                worker,
                deadline_ms,
                cancelled: false,
            },
        );
    }

    /// Renews the leases a worker holds.
    pub fn heartbeat(
        &self,
        worker: &WorkerId,
        leases: &[LeaseId],
        now_ms: i64,
        lease_ms: i64,
    ) -> Vec<Beat> {
        let mut g = self.inner.lock().expect("lease table poisoned");
        g.seen.insert(worker.clone());
        leases
            .iter()
            .map(|id| match g.leases.get_mut(id) {
                Some(e) if &e.worker == worker && e.cancelled => Beat::Cancelled,
                Some(e) if &e.worker == worker => {
                    e.deadline_ms = sched::renew(now_ms, lease_ms);
                    Beat::Active(e.deadline_ms)
                }
                _ => Beat::Lost,
            })
            .collect()
    }

    /// Removes and returns the leases whose deadline passed.
    pub fn take_expired(&self, now_ms: i64) -> Vec<(LeaseId, CellId, SweepId)> {
        let mut g = self.inner.lock().expect("lease table poisoned");
        let ids = sched::expired(g.leases.iter().map(|(id, e)| (*id, e.deadline_ms)), now_ms);
        ids.into_iter()
            .filter_map(|id| g.leases.remove(&id).map(|e| (id, e.cell, e.sweep)))
            .collect()
    }

    /// Removes one lease.
    pub fn remove(&self, lease: LeaseId) {
        self.inner
            .lock()
            .expect("lease table poisoned")
            .leases
            .remove(&lease);
    }

    /// Removes every lease of a cell (it finished).
    pub fn remove_cell(&self, cell: CellId) {
        self.inner
            .lock()
            .expect("lease table poisoned")
            .leases
            .retain(|_, e| e.cell != cell);
    }

    /// Marks the leases of a sweep cancelled; their heartbeats answer `Cancelled`.
    pub fn cancel_sweep(&self, sweep: SweepId) {
        let mut g = self.inner.lock().expect("lease table poisoned");
        for e in g.leases.values_mut().filter(|e| e.sweep == sweep) {
            e.cancelled = true;
        }
    }

    /// Workers seen since the last call.
    pub fn take_seen(&self) -> Vec<WorkerId> {
        self.inner
            .lock()
            .expect("lease table poisoned")
            .seen
            .drain()
            .collect()
    }

    /// Number of live leases.
    pub fn len(&self) -> usize {
        self.inner
            .lock()
            .expect("lease table poisoned")
            .leases
            .len()
    }

    /// True when no lease is live.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn heartbeat_renews_only_own_leases() {
        let t = LeaseTable::default();
        let w = WorkerId("a".into());
        t.insert(LeaseId(1), CellId(1), SweepId(1), w.clone(), 100);
        assert_eq!(
            t.heartbeat(&w, &[LeaseId(1), LeaseId(2)], 50, 1000),
            vec![Beat::Active(1050), Beat::Lost]
        );
        assert_eq!(
            t.heartbeat(&WorkerId("b".into()), &[LeaseId(1)], 50, 1000),
            vec![Beat::Lost]
        );
        assert!(t.take_expired(1049).is_empty());
        assert_eq!(t.take_expired(1050).len(), 1);
        assert_eq!(t.heartbeat(&w, &[LeaseId(1)], 60, 1000), vec![Beat::Lost]);
    }

    #[test]
    fn cancelled_sweeps_stop_their_leases() {
        let t = LeaseTable::default();
        let w = WorkerId("a".into());
        t.insert(LeaseId(1), CellId(1), SweepId(7), w.clone(), 100);
        t.cancel_sweep(SweepId(7));
        assert_eq!(
            t.heartbeat(&w, &[LeaseId(1)], 50, 1000),
            vec![Beat::Cancelled]
        );
    }
}

//! Host-visible staging arenas of a [`super::CommandBatch`]: one for uploads (host writes, the
//! batch copies to the device) and one for read-backs (the batch copies from the device, the
//! host reads after the wait). Arenas outlive submissions, their space handed out anew after
//! each wait, so the pages of a render's staging memory are allocated and faulted in once, not
//! once per tile: fresh host allocations for every tile's inputs wrote at ~1 GB/s on an H200
//! machine (7.1 of the 9.4 s wall time of an 8K five-layer frame).
use std::sync::Arc;

use gpu_allocator::MemoryLocation;

use super::buffer::Buffer;
use super::device::Device;
use crate::Result;

/// Alignment of staging offsets (any element type, and copies that drivers move in wide words).
pub(crate) const STAGING_ALIGN: u64 = 256;
/// Smallest staging arena.
pub(crate) const MIN_STAGING: u64 = 16 << 20;

pub(crate) struct StagingArena {
    location: MemoryLocation,
    name: &'static str,
    /// Space in the last arena is handed out from `used` on.
    arenas: Vec<Buffer>,
    used: u64,
    /// Size of the one arena that replaces several after a submission that needed them.
    capacity: u64,
    /// Read-backs: space of the last submission may still be unread (a [`super::ReadBack`]
    /// holds its arena), so it is handed out anew only once nothing outside holds the arena.
    reuse_only_unshared: bool,
}

impl StagingArena {
    /// The upload arena: what the host wrote is copied by the submission, so after the wait
    /// its space is free whoever still holds a handle.
    pub fn uploads() -> Self {
        Self::new(MemoryLocation::CpuToGpu, "staging arena", false)
    }

    /// The read-back arena: space is free again once the reads of the last submission's
    /// results are done (their handles dropped).
    pub fn read_backs() -> Self {
        Self::new(MemoryLocation::GpuToCpu, "read-back arena", true)
    }

    fn new(location: MemoryLocation, name: &'static str, reuse_only_unshared: bool) -> Self {
        Self { location, name, arenas: Vec::new(), used: 0, capacity: 0, reuse_only_unshared }
    }

    /// `bytes` of the arena for a transfer recorded into the batch: the arena and the offset.
    pub fn space(&mut self, device: &Arc<Device>, bytes: u64) -> Result<(Buffer, u64)> {
        // Offsets stay aligned for any element type.
        let bytes = bytes.max(4).next_multiple_of(STAGING_ALIGN);
        if self.used == 0 && self.reuse_only_unshared && self.arenas.iter().any(Buffer::is_shared) {
            // Unread results of the last submission: leave them to their holders (the arena
            // goes back to the pool when they drop) and take another.
            self.capacity = self.capacity.max(self.bytes());
            self.arenas.clear();
        }
        if let Some(arena) = self.arenas.last() {
            if self.used + bytes <= arena.size() {
                let offset = self.used;
                self.used += bytes;
                return Ok((arena.clone(), offset));
            }
        }
        // A new arena: at least what this submission has used so far (doubling), the capacity
        // an earlier submission needed, and MIN_STAGING.
        let used = self.bytes();
        let size = bytes.max(used).max(self.capacity).max(MIN_STAGING);
        let arena = Buffer::create_on(device, self.name, size, size, self.location)?;
        self.arenas.push(arena.clone());
        self.used = bytes;
        Ok((arena, 0))
    }

    /// Bytes of the arenas held.
    pub fn bytes(&self) -> u64 {
        self.arenas.iter().map(Buffer::size).sum()
    }

    /// After a wait: the arenas' space is free again; several arenas (a submission that
    /// outgrew the first) give way to one of their total size, made at the next request.
    pub fn reset(&mut self) {
        if self.arenas.len() > 1 {
            self.capacity = self.bytes();
            self.arenas.clear();
        }
        self.used = 0;
    }
}

//! Bytes of memory allocated through a [`Context`](super::Context): now and at the peak, by
//! where the memory lives. Every buffer and image allocates through the context's allocator,
//! which reports here, so the figures cover everything, whatever created it.

use std::sync::Mutex;

use gpu_allocator::MemoryLocation;

/// Bytes of allocations by where they live. Sizes are the allocations' own (the device's
/// memory requirements), not the allocator's larger memory blocks they are placed in.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MemoryUse {
    /// Memory only the device reads and writes (images, storage buffers).
    pub device_local: u64,
    /// Memory the host maps: uploads (parameters, staging) and read-back. On a discrete GPU
    /// this is mostly system memory; on a CPU driver every byte is.
    pub host_visible: u64,
}

impl MemoryUse {
    pub fn total(&self) -> u64 {
        self.device_local + self.host_visible
    }
}

#[derive(Debug, Default)]
struct Counts {
    live: MemoryUse,
    /// Each class's largest value since the last reset, taken separately.
    peak: MemoryUse,
    /// The largest sum at any one time since the last reset.
    peak_total: u64,
}

/// Counts live and peak bytes; updated by every allocation and free.
#[derive(Debug, Default)]
pub(crate) struct MemoryMeter {
    counts: Mutex<Counts>,
}

fn slot(use_: &mut MemoryUse, location: MemoryLocation) -> &mut u64 {
    match location {
        MemoryLocation::GpuOnly => &mut use_.device_local,
        _ => &mut use_.host_visible,
    }
}

impl MemoryMeter {
    fn update(&self, f: impl FnOnce(&mut Counts)) {
        // A poisoned lock only means another thread panicked while counting: the counts are
        // plain integers and stay usable.
        let mut c = self.counts.lock().unwrap_or_else(|e| e.into_inner());
        f(&mut c);
    }

    pub(crate) fn allocated(&self, location: MemoryLocation, bytes: u64) {
        self.update(|c| {
            let live = slot(&mut c.live, location);
            *live += bytes;
            let now = *live;
            let peak = slot(&mut c.peak, location);
            *peak = (*peak).max(now);
            c.peak_total = c.peak_total.max(c.live.total());
        });
    }

    pub(crate) fn freed(&self, location: MemoryLocation, bytes: u64) {
        self.update(|c| {
            let live = slot(&mut c.live, location);
            *live = live.saturating_sub(bytes);
        });
    }

    pub(crate) fn in_use(&self) -> MemoryUse {
        let mut out = MemoryUse::default();
        self.update(|c| out = c.live);
        out
    }

    /// Peak per class and the peak of the sum.
    pub(crate) fn peak(&self) -> (MemoryUse, u64) {
        let mut out = (MemoryUse::default(), 0);
        self.update(|c| out = (c.peak, c.peak_total));
        out
    }

    pub(crate) fn reset_peak(&self) {
        self.update(|c| {
            c.peak = c.live;
            c.peak_total = c.live.total();
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn peaks_follow_allocations_and_restart_at_what_is_live() {
        let m = MemoryMeter::default();
        m.allocated(MemoryLocation::GpuOnly, 100);
        m.allocated(MemoryLocation::CpuToGpu, 30);
        m.freed(MemoryLocation::CpuToGpu, 30);
        m.allocated(MemoryLocation::GpuToCpu, 10);
        assert_eq!(
            m.in_use(),
            MemoryUse {
                device_local: 100,
                host_visible: 10
            }
        );
        let (peak, total) = m.peak();
        assert_eq!((peak.device_local, peak.host_visible, total), (100, 30, 130));
        m.freed(MemoryLocation::GpuOnly, 100);
        m.reset_peak();
        let (peak, total) = m.peak();
        assert_eq!((peak.device_local, peak.host_visible, total), (0, 10, 10));
    }
}

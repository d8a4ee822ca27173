//! GPU timestamps: a query pool the recorder writes and the host reads once the submission
//! that wrote it has completed.

use std::sync::Arc;

use ash::vk;

use super::error::{vk_err, GpuError};
use super::Context;

/// A timestamp query pool; read after the submission that wrote it was waited for.
pub struct Timestamps {
    ctx: Arc<Context>,
    pub(crate) pool: vk::QueryPool,
    pub(crate) count: u32,
}

impl Timestamps {
    pub fn new(ctx: &Arc<Context>, count: u32) -> Result<Self, GpuError> {
        let info = vk::QueryPoolCreateInfo::default()
            .query_type(vk::QueryType::TIMESTAMP)
            .query_count(count);
        // SAFETY: valid create info; destroyed in Drop.
        let pool = unsafe { ctx.device.create_query_pool(&info, None) }.map_err(vk_err("vkCreateQueryPool"))?;
        ctx.set_name(pool, "timestamps");
        Ok(Timestamps {
            ctx: ctx.clone(),
            pool,
            count,
        })
    }

    /// Elapsed milliseconds between consecutive timestamps (`count - 1` values).
    pub fn read_ms(&self) -> Result<Vec<f64>, GpuError> {
        self.read_first_ms(self.count)
    }

    /// Elapsed milliseconds between consecutive timestamps among the first `n` (all written
    /// since the last reset: an unwritten one is never available).
    pub fn read_first_ms(&self, n: u32) -> Result<Vec<f64>, GpuError> {
        let mut ticks = vec![0u64; n.min(self.count) as usize];
        // SAFETY: the pool was written by a submission that has completed.
        unsafe {
            self.ctx.device.get_query_pool_results(
                self.pool,
                0,
                &mut ticks,
                vk::QueryResultFlags::TYPE_64 | vk::QueryResultFlags::WAIT,
            )
        }
        .map_err(vk_err("vkGetQueryPoolResults"))?;
        let bits = {
            // SAFETY: plain query on a valid physical device.
            let families = unsafe {
                self.ctx
                    .instance
                    .get_physical_device_queue_family_properties(self.ctx.physical)
            };
            families
                .get(self.ctx.queue_family as usize)
                .map(|f| f.timestamp_valid_bits)
                .unwrap_or(64)
        };
        let mask = if bits >= 64 { u64::MAX } else { (1u64 << bits) - 1 };
        let period = self.ctx.timestamp_period_ns();
        Ok(ticks
            .windows(2)
            .map(|w| ((w[1].wrapping_sub(w[0])) & mask) as f64 * period / 1.0e6)
            .collect())
    }
}

impl Drop for Timestamps {
    fn drop(&mut self) {
        if self.ctx.is_hung() {
            return;
        }
        // SAFETY: no pending submission uses the pool.
        unsafe { self.ctx.device.destroy_query_pool(self.pool, None) };
    }
}

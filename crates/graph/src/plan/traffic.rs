//! The plan's estimate of the memory traffic of a frame, by kind (compile's last phase,
//! `compile/traffic.rs`, computes it).

#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum TrafficModel {
    Tiler,
    Immediate,
}

impl TrafficModel {
    pub const fn name(self) -> &'static str {
        match self {
            TrafficModel::Tiler => "tiler",
            TrafficModel::Immediate => "immediate",
        }
    }
}

/// Bytes per frame, by kind of traffic.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash)]
pub struct TrafficBreakdown {
    /// Tiler: LOADs into tile memory. Immediate: attachment reads.
    pub attachment_read_bytes: u64,
    /// Tiler: STOREs out of tile memory. Immediate: attachment writes.
    pub attachment_write_bytes: u64,
    /// Multisample resolves written to memory.
    pub resolve_write_bytes: u64,
    pub sampled_read_bytes: u64,
    pub storage_read_bytes: u64,
    pub storage_write_bytes: u64,
    /// Uniform, vertex, index and indirect buffers.
    pub buffer_read_bytes: u64,
    pub transfer_read_bytes: u64,
    pub transfer_write_bytes: u64,
}

impl TrafficBreakdown {
    pub fn total_bytes(&self) -> u64 {
        [
            self.attachment_read_bytes,
            self.attachment_write_bytes,
            self.resolve_write_bytes,
            self.sampled_read_bytes,
            self.storage_read_bytes,
            self.storage_write_bytes,
            self.buffer_read_bytes,
            self.transfer_read_bytes,
            self.transfer_write_bytes,
        ]
        .iter()
        .fold(0u64, |acc, &b| acc.saturating_add(b))
    }

    /// Named parts, for printing.
    pub fn parts(&self) -> [(&'static str, u64); 9] {
        [
            ("attachment reads/loads", self.attachment_read_bytes),
            ("attachment writes/stores", self.attachment_write_bytes),
            ("resolves", self.resolve_write_bytes),
            ("sampled reads", self.sampled_read_bytes),
            ("storage reads", self.storage_read_bytes),
            ("storage writes", self.storage_write_bytes),
            ("uniform/vertex/index/indirect", self.buffer_read_bytes),
            ("transfer reads", self.transfer_read_bytes),
            ("transfer writes", self.transfer_write_bytes),
        ]
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct TrafficEstimate {
    pub model: TrafficModel,
    /// The compiled plan.
    pub planned: TrafficBreakdown,
    /// Every raster pass alone, loading and storing every attachment.
    pub naive: TrafficBreakdown,
}

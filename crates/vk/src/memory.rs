//! Memory: buffers and images in the memory type the profile picks per use, mapped writes and
//! reads (flushed and invalidated where the type is not coherent), through gpu-allocator.

use std::sync::atomic::Ordering;

use ash::vk;
use gpu_allocator::vulkan::{Allocation, AllocationCreateDesc, AllocationScheme};
use gpu_allocator::MemoryLocation;
use tilegraph_profile::{select_memory_type, MemoryChoice, MemoryUse};

use crate::context::Context;
use crate::error::{VkError, VkResultExt};

/// A buffer and its memory.
#[derive(Debug)]
pub struct Buffer {
    pub raw: vk::Buffer,
    pub size: u64,
    pub memory: MemoryChoice,
    allocation: Allocation,
}

impl Buffer {
    /// The mapped bytes, when the memory type is host-visible.
    pub fn mapped(&self) -> Option<&[u8]> {
        self.allocation.mapped_slice()
    }
    pub fn mapped_mut(&mut self) -> Option<&mut [u8]> {
        self.allocation.mapped_slice_mut()
    }
    /// Memory property flags of the allocation, as gpu-allocator reports them.
    pub fn memory_properties(&self) -> vk::MemoryPropertyFlags {
        self.allocation.memory_properties()
    }
}

/// An image and its memory.
#[derive(Debug)]
pub struct Image {
    pub raw: vk::Image,
    pub format: vk::Format,
    pub extent: vk::Extent2D,
    pub mip_levels: u32,
    pub memory: MemoryChoice,
    allocation: Allocation,
}

impl Image {
    pub fn memory_properties(&self) -> vk::MemoryPropertyFlags {
        self.allocation.memory_properties()
    }
}

impl Context {
    /// The queue families a buffer is shared between: both, concurrently, where the async
    /// compute queue is of another family than the graphics queue (either may read any of
    /// tilegraph's buffers; a buffer has no compression for exclusive ownership to keep);
    /// `None`: exclusive, one family.
    pub fn buffer_families(&self) -> Option<[u32; 2]> {
        self.async_queue
            .filter(|q| q.family != self.queue_family)
            .map(|q| [self.queue_family, q.family])
    }

    /// Number of device-memory allocations made through this context so far.
    pub fn allocation_count(&self) -> u64 {
        self.allocations.load(Ordering::Relaxed)
    }

    /// Bytes of device memory tilegraph holds now (every allocation through this context).
    pub fn allocated_bytes(&self) -> u64 {
        self.allocated_bytes.load(Ordering::Relaxed)
    }

    /// Caps the device memory tilegraph may hold: an allocation past `bytes` fails with
    /// [`VkError::OutOfMemory`], as the driver's would, and the frame that needed it fails
    /// cleanly (the next one retries). `None` lifts the cap. For an engine that shares the
    /// device's memory with tilegraph — and for tests that inject out-of-memory.
    pub fn set_memory_budget(&self, bytes: Option<u64>) {
        self.memory_budget
            .store(bytes.unwrap_or(u64::MAX), Ordering::Relaxed);
    }

    /// The memory type the profile picks for `use_` among `type_bits`.
    pub fn choose_memory(&self, use_: MemoryUse, type_bits: u32) -> Result<MemoryChoice, VkError> {
        Ok(select_memory_type(
            &self.profile().memory,
            &self.physical.identity.memory_types,
            type_bits,
            use_,
        )?)
    }

    /// Allocates memory for `requirements` in exactly the type the profile chooses: the
    /// requirement's type bits are narrowed to that one type before gpu-allocator sees them.
    pub fn allocate(
        &self,
        name: &str,
        requirements: vk::MemoryRequirements,
        use_: MemoryUse,
        linear: bool,
    ) -> Result<(Allocation, MemoryChoice), VkError> {
        self.injected_fault_at(
            crate::FaultSite::Allocation,
            "vkAllocateMemory (injected fault)",
        )?;
        let budget = self.memory_budget.load(Ordering::Relaxed);
        if self.allocated_bytes().saturating_add(requirements.size) > budget {
            log::warn!(
                "memory for {name:?} ({} bytes) would exceed the budget of {budget} bytes ({} held)",
                requirements.size,
                self.allocated_bytes()
            );
            return Err(VkError::OutOfMemory {
                call: "allocation within the context's memory budget",
                kind: "device",
            });
        }
        let choice = self.choose_memory(use_, requirements.memory_type_bits)?;
        let narrowed = vk::MemoryRequirements {
            memory_type_bits: 1 << choice.type_index,
            ..requirements
        };
        let mut allocator = self.allocator.lock().map_err(|_| VkError::Invalid {
            what: "allocator".into(),
            reason: "a thread panicked while holding it".into(),
        })?;
        let allocation = allocator
            .allocate(&AllocationCreateDesc {
                name,
                requirements: narrowed,
                // Unknown: let the narrowed type bits alone decide; gpu-allocator maps the
                // memory whenever the type is host-visible.
                location: MemoryLocation::Unknown,
                linear,
                allocation_scheme: AllocationScheme::GpuAllocatorManaged,
            })
            .map_err(|source| VkError::Allocation {
                name: name.to_string(),
                source,
            })?;
        self.allocations.fetch_add(1, Ordering::Relaxed);
        self.allocated_bytes
            .fetch_add(allocation.size(), Ordering::Relaxed);
        Ok((allocation, choice))
    }

    pub fn free(&self, allocation: Allocation) {
        self.allocated_bytes
            .fetch_sub(allocation.size(), Ordering::Relaxed);
        match self.allocator.lock() {
            Ok(mut a) => {
                if let Err(e) = a.free(allocation) {
                    log::error!("freeing device memory: {e}");
                }
            }
            Err(_) => log::error!("allocator lock poisoned; leaking an allocation"),
        }
    }

    /// Creates a buffer in the memory type the profile picks for `use_`.
    pub fn create_buffer(
        &self,
        name: &str,
        size: u64,
        usage: vk::BufferUsageFlags,
        use_: MemoryUse,
    ) -> Result<Buffer, VkError> {
        if size == 0 {
            return Err(VkError::Invalid {
                what: format!("buffer {name:?}"),
                reason: "size is zero".into(),
            });
        }
        let families = self.buffer_families();
        let info = match &families {
            Some(f) => vk::BufferCreateInfo::default()
                .sharing_mode(vk::SharingMode::CONCURRENT)
                .queue_family_indices(f),
            None => vk::BufferCreateInfo::default().sharing_mode(vk::SharingMode::EXCLUSIVE),
        }
        .size(size)
        .usage(usage);
        // SAFETY: valid create info with non-zero size.
        let raw = unsafe { self.device.create_buffer(&info, None) }.vk("vkCreateBuffer")?;
        // SAFETY: raw is a live buffer of this device.
        let req = unsafe { self.device.get_buffer_memory_requirements(raw) };
        let (allocation, memory) = match self.allocate(name, req, use_, true) {
            Ok(a) => a,
            Err(e) => {
                // SAFETY: unbound, unused buffer.
                unsafe { self.device.destroy_buffer(raw, None) };
                return Err(e);
            }
        };
        // SAFETY: the allocation satisfies the buffer's requirements (size, alignment, type).
        if let Err(r) = unsafe {
            self.device
                .bind_buffer_memory(raw, allocation.memory(), allocation.offset())
        } {
            // SAFETY: unused buffer; allocation returned to the allocator.
            unsafe { self.device.destroy_buffer(raw, None) };
            self.free(allocation);
            return Err(VkError::call("vkBindBufferMemory", r));
        }
        self.set_name(raw, name);
        Ok(Buffer {
            raw,
            size,
            memory,
            allocation,
        })
    }

    /// The range of a buffer's memory to flush or invalidate: atom-aligned, and never past the
    /// end of its memory object (a dedicated allocation's object is exactly its size, which
    /// need not be a multiple of the atom: that range runs to `VK_WHOLE_SIZE`).
    fn mapped_range(&self, buffer: &Buffer) -> vk::MappedMemoryRange<'static> {
        let atom = self.physical.limits.non_coherent_atom_size.max(1);
        let a = &buffer.allocation;
        let start = a.offset() / atom * atom;
        // SAFETY: the allocation's memory object is live while the buffer is.
        let range = vk::MappedMemoryRange::default().memory(unsafe { a.memory() });
        if a.is_dedicated() {
            return range.offset(start).size(vk::WHOLE_SIZE);
        }
        // Sub-allocated: gpu-allocator's blocks are far larger than an atom and sized in
        // multiples of it, so rounding up stays inside the block.
        let end = (a.offset() + a.size()).div_ceil(atom) * atom;
        range.offset(start).size(end - start)
    }

    fn is_coherent(buffer: &Buffer) -> bool {
        buffer
            .memory
            .flags
            .contains(tilegraph_profile::MemoryFlags::HOST_COHERENT)
    }

    /// Makes GPU writes visible to the host for a mapped buffer in non-coherent memory (no-op on
    /// coherent memory). Call after the fence that covers the writes.
    pub fn invalidate_mapped(&self, buffer: &Buffer) -> Result<(), VkError> {
        if Self::is_coherent(buffer) {
            return Ok(());
        }
        let range = self.mapped_range(buffer);
        // SAFETY: the memory is mapped by gpu-allocator; the range is atom-aligned and inside it.
        unsafe { self.device.invalidate_mapped_memory_ranges(&[range]) }
            .vk("vkInvalidateMappedMemoryRanges")
    }

    /// Makes host writes to a mapped buffer in non-coherent memory visible to the device (no-op
    /// on coherent memory). Call before submitting work that reads them.
    pub fn flush_mapped(&self, buffer: &Buffer) -> Result<(), VkError> {
        if Self::is_coherent(buffer) {
            return Ok(());
        }
        let range = self.mapped_range(buffer);
        // SAFETY: as for `invalidate_mapped`.
        unsafe { self.device.flush_mapped_memory_ranges(&[range]) }.vk("vkFlushMappedMemoryRanges")
    }

    /// Copies `bytes` into a mapped buffer at `offset` and flushes it (non-coherent memory):
    /// the one way the host writes GPU-visible memory. Errors when the buffer is not mapped or
    /// too small.
    pub fn write_mapped(
        &self,
        buffer: &mut Buffer,
        offset: usize,
        bytes: &[u8],
    ) -> Result<(), VkError> {
        let size = buffer.size;
        let target = buffer
            .mapped_mut()
            .and_then(|m| m.get_mut(offset..offset.checked_add(bytes.len())?));
        let Some(target) = target else {
            return Err(VkError::Invalid {
                what: format!("buffer of {size} bytes"),
                reason: format!(
                    "cannot write {} bytes at offset {offset}: not host-visible or too small",
                    bytes.len()
                ),
            });
        };
        target.copy_from_slice(bytes);
        self.flush_mapped(buffer)
    }

    pub fn destroy_buffer(&self, buffer: Buffer) {
        // SAFETY: the caller guarantees the GPU no longer uses the buffer.
        unsafe { self.device.destroy_buffer(buffer.raw, None) };
        self.free(buffer.allocation);
    }

    /// Creates a 2D image in the memory type the profile picks for `use_`.
    pub fn create_image(
        &self,
        name: &str,
        info: &vk::ImageCreateInfo<'_>,
        use_: MemoryUse,
    ) -> Result<Image, VkError> {
        if info.extent.width == 0 || info.extent.height == 0 {
            return Err(VkError::Invalid {
                what: format!("image {name:?}"),
                reason: "zero extent".into(),
            });
        }
        // SAFETY: valid create info (checked extent; format/usage validated by the layer).
        let raw = unsafe { self.device.create_image(info, None) }.vk("vkCreateImage")?;
        // SAFETY: live image.
        let req = unsafe { self.device.get_image_memory_requirements(raw) };
        let linear = info.tiling == vk::ImageTiling::LINEAR;
        let (allocation, memory) = match self.allocate(name, req, use_, linear) {
            Ok(a) => a,
            Err(e) => {
                // SAFETY: unbound, unused image.
                unsafe { self.device.destroy_image(raw, None) };
                return Err(e);
            }
        };
        // SAFETY: allocation satisfies the requirements.
        if let Err(r) = unsafe {
            self.device
                .bind_image_memory(raw, allocation.memory(), allocation.offset())
        } {
            // SAFETY: unused image.
            unsafe { self.device.destroy_image(raw, None) };
            self.free(allocation);
            return Err(VkError::call("vkBindImageMemory", r));
        }
        self.set_name(raw, name);
        Ok(Image {
            raw,
            format: info.format,
            extent: vk::Extent2D {
                width: info.extent.width,
                height: info.extent.height,
            },
            mip_levels: info.mip_levels,
            memory,
            allocation,
        })
    }

    pub fn destroy_image(&self, image: Image) {
        // SAFETY: the caller guarantees the GPU no longer uses the image.
        unsafe { self.device.destroy_image(image.raw, None) };
        self.free(image.allocation);
    }
}

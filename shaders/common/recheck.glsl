// Temporal coherence of the occlusion tests (knob occlusion_recheck, after CHC++): an item found
// visible is drawn untested and its box tested again once every `interval` frames, staggered by
// item. `packed` = interval | offset << 16, offset = frame % interval (cull::Recheck on the CPU).
bool recheck_carries(uint packed, uint item) {
    uint interval = max(packed & 0xFFFFu, 1u);
    return ((item + (packed >> 16u)) % interval) != 0u;
}

// Raster occlusion's per-instance word: bit 0 a box fragment passed this frame, bit 1 drawn
// last frame (written by cull.comp after it read both).
const uint FLAG_PASSED = 1u;
const uint FLAG_DRAWN = 2u;

// Whether an instance whose word is `word` skips its box test this frame: drawn last frame and
// not its turn.
bool raster_carried(uint word, uint packed, uint id) {
    return (word & FLAG_DRAWN) != 0u && recheck_carries(packed, id);
}

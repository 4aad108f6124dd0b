//! The GPU HiZ pyramid equals the CPU reference (tilegraph-cull) exactly.

//! GPU hierarchical-Z pyramid build (see docs/CULLING.md for the algorithm it must match).

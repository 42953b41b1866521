//! Initial values from nothing but image measurements and approximate intrinsics.

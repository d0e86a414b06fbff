//! The global allocator of the bench binaries and the callgrind driver: the one the Python
//! extension ships with (`native/python/src/lib.rs`), so that their figures are the product's.

#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

//! Small shared tools: durable file writes, allocator tuning, progress reporting, the
//! seeded random number generator and sharding (`--shard I/N`, `merge`).

pub(crate) mod durable;
pub mod heap;
pub(crate) mod progress;
pub mod rng;
pub mod shard;

//! Small shared tools: durable file writes, allocator tuning, progress reporting and the
//! seeded random number generator.

pub(crate) mod durable;
pub mod heap;
pub(crate) mod progress;
pub mod rng;

//! Small shared tools: durable file writes, allocator tuning, progress reporting and the
//! seeded random number generator.

pub mod durable;
pub mod heap;
pub mod progress;
pub mod rng;

//! Request handlers, one module per area.

pub mod admin;
pub mod classify;
pub mod health;
pub mod models;
pub mod v2;

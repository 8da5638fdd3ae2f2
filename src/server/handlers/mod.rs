//! Request handlers, one module per area.

pub(crate) mod admin;
pub(crate) mod classify;
pub(crate) mod datasets;
pub(crate) mod health;
pub(crate) mod input;
pub(crate) mod locate;
pub(crate) mod material;
pub(crate) mod models;
pub(crate) mod preview;
pub(crate) mod v2;
pub(crate) mod web;

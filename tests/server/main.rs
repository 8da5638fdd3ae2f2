//! The service: the data plane and the admin plane against the real router, the OpenAPI
//! contract, the hostile-input corpus, and crash safety and faults with the real binary.

#[path = "../common/mod.rs"]
mod common;

mod admin;
mod api;
mod bodies;
mod datasets;
mod faults;
mod honest;
mod hostile;
mod openapi;
mod page;
mod replicas;
mod shapes;
mod v2;

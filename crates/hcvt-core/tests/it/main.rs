//! The core's integration tests, one module per file, linked as ONE test binary: each
//! separate binary re-ran the (thin-LTO) code generation and link of the whole core, the
//! largest part of `cargo test --release`'s build time. Helpers shared by the modules are
//! `tests/common`.

#[path = "../common/mod.rs"]
mod common;

mod density;
mod diagram_3d;
mod fingerprints;
mod optimise;
mod periodic;
mod power;
mod properties;
mod quality;
mod warm_start;

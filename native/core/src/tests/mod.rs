//! Unit tests that reach into the crate's internals, with the cages of the integration tests.

#[path = "../../tests/common/mod.rs"]
mod common;

mod classic;
mod invariants;

//! What the test files of marie-actors share (each is a binary of its own and includes
//! this module with `mod common;`).

// each test binary uses its own subset
#![allow(dead_code)]

pub(crate) mod ops;

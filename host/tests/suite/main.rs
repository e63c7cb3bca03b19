//! The tool's tests: the library's end-to-end behaviour and the `rollfuse` command line.
//!
//! One test binary, one module per subject (`cargo test -p rollfuse --test suite
//! registration::` runs one subject). One binary links the tool's libraries once instead of
//! once a file, and its long tests (the demo, fine-tuning, the full-disk reruns, the docs'
//! examples) share the cores with each other instead of waiting for the file before.

mod common;
mod session;

mod anomaly;
mod cli;
mod demo;
mod depth;
mod depth_cli;
mod detect;
mod device_roll;
mod doc_examples;
mod eval;
mod fixture_roll;
mod float_vs_fixed;
mod full_disk;
mod fuse_cli;
mod http_fuzz;
mod installed;
mod layers;
mod metrics;
mod out_rule;
mod records_cli;
mod registration;
mod roll;
mod serve;
mod serve_limits;
mod simulator;
mod stream;
mod stream_fuzz;
mod tradeoff;
mod tune;
mod untrusted;

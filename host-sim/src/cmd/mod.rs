//! One module per `host-sim` subcommand: its arguments and its `run`.
pub mod analyze;
pub mod bench;
pub mod bpf_bench;
pub mod fly;
pub mod id_dataset;
pub mod simulate;

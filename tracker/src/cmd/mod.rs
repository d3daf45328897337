//! One module per `aim` subcommand: its arguments and its `run`.
pub mod frames;
pub mod record;
pub mod replay;
pub mod track;

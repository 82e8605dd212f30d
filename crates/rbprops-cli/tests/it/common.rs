//! Helpers shared by the CLI's tests.

use std::process::Command;

/// The `rbprops` executable of this build.
pub fn rbprops() -> Command {
    Command::new(env!("CARGO_BIN_EXE_rbprops"))
}

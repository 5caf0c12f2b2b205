//! One file per subcommand.

pub mod bake;
pub mod basis;
pub mod bench;
pub mod compare;
pub mod farm;
pub mod info;
pub mod merge;
pub mod reference;
pub mod relight;
pub mod report;

use serde::Serialize;

/// Prints `value` as one line of JSON on stdout.
pub fn print_json<T: Serialize>(value: &T) {
    match serde_json::to_string(value) {
        Ok(s) => println!("{s}"),
        Err(e) => eprintln!("relume: could not encode the summary as JSON: {e}"),
    }
}

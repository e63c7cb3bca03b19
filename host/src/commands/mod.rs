//! The `rollfuse` subcommands: argument parsing (clap) and what each one does.

pub mod bars;
pub mod demo;
pub mod depth;
pub mod detect;
pub mod eval;
pub mod fuse;
pub mod metrics;
pub mod rolls;
pub mod side_files;
pub mod simulate;
pub mod splice;
pub mod stream;
pub mod tradeoff;

use rollfuse::names::Named;

/// A command wrote its output, but the output rests on evidence it cannot trust (a
/// roll's placement with the belt lost, say): the process exits with
/// [`Untrusted::EXIT_CODE`], not 0, unless the user accepted that.
#[derive(Debug)]
pub struct Untrusted(pub String);

impl Untrusted {
    /// The exit code of an untrusted output (1 is any other failure).
    pub const EXIT_CODE: u8 = 3;
}

impl std::fmt::Display for Untrusted {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for Untrusted {}

/// clap's parser of a [`Named`] setting: its names are the possible values, each with its
/// line of help.
pub fn named<T: Named>() -> impl clap::builder::TypedValueParser<Value = T> {
    use clap::builder::TypedValueParser;
    let values = T::VALUES
        .iter()
        .map(|&(name, help, _)| clap::builder::PossibleValue::new(name).help(help));
    clap::builder::PossibleValuesParser::new(values)
        .try_map(|name| T::from_name(&name).ok_or("not one of the possible values"))
}

pub use rollfuse::files::check_writable;

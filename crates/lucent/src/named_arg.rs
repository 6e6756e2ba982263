//! The command-line side of [`Named`] enums: a clap value parser whose
//! possible values (in `--help` and in errors) are the enum's name table.
//!
//! `lucent-bench` includes this file with `#[path]`, so both binaries offer
//! the same names the same way; clap stays out of lucent-geom, where the
//! tables live, and four lines are not worth a crate.

use lucent_geom::Named;

/// A flag whose values are a [`Named`] enum's names (listed in `--help`
/// and in the error for any other value).
pub fn named<T: Named>() -> impl clap::builder::TypedValueParser<Value = T> {
    use clap::builder::TypedValueParser;
    clap::builder::PossibleValuesParser::new(T::NAMES.iter().map(|&(n, _)| n))
        .try_map(|name| T::from_name(&name).ok_or_else(|| format!("expected {}", T::name_list())))
}

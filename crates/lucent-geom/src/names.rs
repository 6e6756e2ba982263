//! One name table per setting enum, shared by every place that reads or
//! prints the setting: the scene file, the command line and the viewer.

/// An enum of settings whose every value has one lowercase name.
///
/// The table [`NAMES`](Named::NAMES) is the only place the names are
/// written; parsing ([`from_name`](Named::from_name)), printing
/// ([`name`](Named::name)) and the lists in error messages
/// ([`name_list`](Named::name_list)) all read it.
///
/// ```
/// use lucent_geom::{Named, TriangleTest};
/// assert_eq!(TriangleTest::from_name("moller-trumbore"), Some(TriangleTest::MollerTrumbore));
/// assert_eq!(TriangleTest::Watertight.name(), "watertight");
/// assert_eq!(TriangleTest::name_list(), "watertight or moller-trumbore");
/// ```
pub trait Named: Copy + PartialEq + Send + Sync + 'static {
    /// Every value with its name, in the order help text lists them.
    const NAMES: &'static [(&'static str, Self)];

    /// The value called `name` (exact, lowercase).
    fn from_name(name: &str) -> Option<Self> {
        Self::NAMES.iter().find(|(n, _)| *n == name).map(|&(_, v)| v)
    }

    /// This value's name (`""` only if the table missed a value, which
    /// each table's test rules out).
    fn name(self) -> &'static str {
        Self::NAMES.iter().find(|(_, v)| *v == self).map_or("", |(n, _)| n)
    }

    /// The names as prose: `a`, `a or b`, `a, b or c`.
    fn name_list() -> String {
        match Self::NAMES.split_last() {
            None => String::new(),
            Some(((last, _), [])) => (*last).to_owned(),
            Some(((last, _), rest)) => {
                let rest: Vec<&str> = rest.iter().map(|(n, _)| *n).collect();
                format!("{} or {last}", rest.join(", "))
            }
        }
    }
}

/// Checks a [`Named`] table against every value the caller lists: each
/// value has exactly one name, and names are unique, lowercase and round
/// trip. For the tables' own tests.
///
/// # Panics
///
/// When the table fails a check (this is a test helper).
#[doc(hidden)]
pub fn assert_table<T: Named + std::fmt::Debug>(all: &[T]) {
    assert_eq!(T::NAMES.len(), all.len(), "one name per value");
    for &v in all {
        let name = v.name();
        assert!(!name.is_empty(), "{v:?} has no name");
        assert!(name.chars().all(|c| c.is_ascii_lowercase() || c == '-'), "{name:?}");
        assert_eq!(T::from_name(name), Some(v), "{name}");
    }
    assert_eq!(T::from_name("no-such-name"), None);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::TriangleTest;

    #[test]
    fn the_triangle_test_table_is_complete() {
        assert_table(&[TriangleTest::Watertight, TriangleTest::MollerTrumbore]);
        assert_eq!(TriangleTest::from_name("Watertight"), None);
    }
}

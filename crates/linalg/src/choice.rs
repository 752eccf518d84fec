//! Named choices: enums with one parser, used by scene files, the command line and reports.
//!
//! A [`Choice`] is a small `Copy` enum with a fixed list of names. [`impl_choice!`]
//! derives `FromStr`, `Display`, serde's `Serialize` and `Deserialize` from that list,
//! so every place that reads or prints the choice agrees, and an unknown name is a
//! [`ParseChoiceError`] that lists the accepted ones.

use std::fmt;

/// A choice among a fixed set of named values.
pub trait Choice: Sized + Copy + PartialEq + 'static {
    /// What the choice is called in messages (`backend`, `mode`).
    const WHAT: &'static str;
    /// Every value, in the order messages list them.
    const ALL: &'static [Self];
    /// The name used in scene files, on the command line and in reports.
    fn name(self) -> &'static str;

    /// Parses a name; an unknown one is an error listing the accepted names.
    fn parse_name(s: &str) -> Result<Self, ParseChoiceError> {
        Self::ALL.iter().copied().find(|c| c.name() == s).ok_or_else(|| ParseChoiceError {
            what: Self::WHAT,
            given: s.to_string(),
            expected: Self::ALL.iter().map(|c| c.name()).collect::<Vec<_>>().join(", "),
        })
    }
}

/// A name that is not one of a [`Choice`]'s values.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ParseChoiceError {
    /// What was being chosen.
    pub what: &'static str,
    /// The name given.
    pub given: String,
    /// The accepted names, comma separated.
    pub expected: String,
}

impl fmt::Display for ParseChoiceError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "`{}` is not a {} (expected one of: {})", self.given, self.what, self.expected)
    }
}

impl std::error::Error for ParseChoiceError {}

/// Implements `FromStr`, `Display`, `Serialize` and `Deserialize` for a [`Choice`]
/// through its names. The crate using it must depend on `serde`.
#[macro_export]
macro_rules! impl_choice {
    ($t:ty) => {
        impl ::std::str::FromStr for $t {
            type Err = $crate::ParseChoiceError;
            fn from_str(s: &str) -> ::std::result::Result<Self, Self::Err> {
                <$t as $crate::Choice>::parse_name(s)
            }
        }
        impl ::std::fmt::Display for $t {
            fn fmt(&self, f: &mut ::std::fmt::Formatter<'_>) -> ::std::fmt::Result {
                f.pad($crate::Choice::name(*self))
            }
        }
        impl ::serde::Serialize for $t {
            fn serialize<S: ::serde::Serializer>(&self, s: S) -> ::std::result::Result<S::Ok, S::Error> {
                s.serialize_str($crate::Choice::name(*self))
            }
        }
        impl<'de> ::serde::Deserialize<'de> for $t {
            fn deserialize<D: ::serde::Deserializer<'de>>(d: D) -> ::std::result::Result<Self, D::Error> {
                let s = <::std::borrow::Cow<'de, str> as ::serde::Deserialize>::deserialize(d)?;
                <$t as $crate::Choice>::parse_name(&s).map_err(::serde::de::Error::custom)
            }
        }
    };
}

//! Named enums: one table of variant names per enum, shared by the config file, the CLI, the
//! panel and the JSON schema.
//!
//! [`named_enum!`](crate::named_enum) takes an enum's values in order with their names and
//! derives from that one table everything that reads or writes a name: `ALL`, `NAMES`,
//! `name()`, `from_name()`, `Display`, `FromStr`, serde (the value is its name), clap's
//! `ValueEnum` (`--help` lists the values, typos get suggestions, shell completions know them)
//! and `schemars::JsonSchema` (an enum of the names, for editors validating a config).

/// Declares the names of an enum's values (see the module documentation). The enum must be
/// `Copy + PartialEq`; every value must be listed, in the order the panel and `--help` show
/// them (a test in `tests/cli.rs` checks the names are unique and round-trip).
///
/// ```ignore
/// named_enum!(GamepadMode { Self::Navigate => "navigate", Self::Head => "head" });
/// ```
#[macro_export]
macro_rules! named_enum {
    ($ty:ident { $($value:expr => $name:literal),+ $(,)? }) => {
        impl $ty {
            /// Every value, in the order the CLI, the panel and the schema list them.
            pub const ALL: [$ty; [$($name),+].len()] = [$($value),+];
            /// The name of each value of [`Self::ALL`], as the config and the CLI write it.
            pub const NAMES: &'static [&'static str] = &[$($name),+];

            /// The name used by the config file, the CLI and the panel.
            pub fn name(self) -> &'static str {
                Self::ALL
                    .iter()
                    .position(|v| *v == self)
                    .map_or("", |i| Self::NAMES[i])
            }

            /// The value of a config or CLI name.
            pub fn from_name(name: &str) -> Option<Self> {
                Self::ALL
                    .into_iter()
                    .zip(Self::NAMES)
                    .find(|(_, n)| **n == name)
                    .map(|(v, _)| v)
            }
        }

        impl std::fmt::Display for $ty {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str(self.name())
            }
        }

        impl std::str::FromStr for $ty {
            type Err = String;
            fn from_str(s: &str) -> Result<Self, String> {
                Self::from_name(s).ok_or_else(|| {
                    format!("unknown value '{s}'; expected one of: {}", Self::NAMES.join(", "))
                })
            }
        }

        impl serde::Serialize for $ty {
            fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
                s.serialize_str(self.name())
            }
        }

        impl<'de> serde::Deserialize<'de> for $ty {
            fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
                let name = <String as serde::Deserialize>::deserialize(d)?;
                Self::from_name(name.trim()).ok_or_else(|| {
                    <D::Error as serde::de::Error>::unknown_variant(&name, Self::NAMES)
                })
            }
        }

        impl clap::ValueEnum for $ty {
            fn value_variants<'a>() -> &'a [Self] {
                &Self::ALL
            }
            fn to_possible_value(&self) -> Option<clap::builder::PossibleValue> {
                Some(clap::builder::PossibleValue::new(self.name()))
            }
        }

        impl schemars::JsonSchema for $ty {
            fn schema_name() -> std::borrow::Cow<'static, str> {
                stringify!($ty).into()
            }
            fn json_schema(_: &mut schemars::SchemaGenerator) -> schemars::Schema {
                schemars::json_schema!({ "type": "string", "enum": Self::NAMES })
            }
        }
    };
}

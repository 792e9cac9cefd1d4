//! Words of the protocol that people type: every closed set of choices (a meta action,
//! an action type, a style, a game, an end reason) has its names written once, here, by
//! `named!`, which gives the set `ALL`, `name()`, `Display` and a `FromStr` whose error
//! lists the valid names. Clients, the CLI, scenario files and docs all read these.

use std::fmt;

/// Occurs when a name is not one of its set's.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct UnknownName {
    /// What was being named ("meta action").
    pub what: &'static str,
    /// The name given.
    pub given: String,
    /// The valid names, comma-separated.
    pub valid: String,
}

impl fmt::Display for UnknownName {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "unknown {} '{}': use one of {}", self.what, self.given, self.valid)
    }
}

impl std::error::Error for UnknownName {}

/// `ALL`, `name`, `Display` and `FromStr` for a fieldless enum, from one list of
/// `Variant => "name"`.
macro_rules! named {
    ($ty:ident, $what:literal, { $($variant:ident => $name:literal),+ $(,)? }) => {
        impl $ty {
            /// Every choice, in declaration (and wire) order.
            pub const ALL: [$ty; [$($name),+].len()] = [$($ty::$variant),+];

            /// The name people write.
            pub fn name(self) -> &'static str {
                match self {
                    $($ty::$variant => $name),+
                }
            }
        }

        impl ::std::fmt::Display for $ty {
            fn fmt(&self, f: &mut ::std::fmt::Formatter<'_>) -> ::std::fmt::Result {
                f.write_str(self.name())
            }
        }

        impl ::std::str::FromStr for $ty {
            type Err = $crate::names::UnknownName;
            fn from_str(text: &str) -> Result<Self, Self::Err> {
                Self::ALL.into_iter().find(|choice| choice.name() == text).ok_or_else(|| {
                    $crate::names::UnknownName {
                        what: $what,
                        given: text.to_string(),
                        valid: Self::ALL.map($ty::name).join(", "),
                    }
                })
            }
        }
    };
}

pub(crate) use named;

#[cfg(test)]
mod tests {
    use crate::{ActionType, EndReason, Game, MetaAction, ObservationKind, Style};

    fn round_trips<T: std::str::FromStr + std::fmt::Display + PartialEq + std::fmt::Debug + Copy>(all: &[T]) {
        for &choice in all {
            assert_eq!(choice.to_string().parse::<T>().ok(), Some(choice));
        }
    }

    #[test]
    fn every_name_parses_back_and_an_unknown_one_lists_the_valid_ones() {
        round_trips(&MetaAction::ALL);
        round_trips(&ActionType::ALL);
        round_trips(&ObservationKind::ALL);
        round_trips(&Style::ALL);
        round_trips(&Game::ALL);
        round_trips(&EndReason::ALL);
        round_trips(&crate::GtRole::ALL);
        round_trips(&crate::Fault::ALL);
        let error = "sideways".parse::<MetaAction>().unwrap_err().to_string();
        assert_eq!(error, "unknown meta action 'sideways': use one of lane_left, idle, lane_right, faster, slower");
        assert_eq!("nash".parse::<Game>(), Ok(Game::Nash));
        assert_eq!("kinematics_with_mask".parse::<ObservationKind>(), Ok(ObservationKind::KinematicsWithMask));
    }
}

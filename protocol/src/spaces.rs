//! Space specs that map one-to-one onto Gymnasium spaces (Box, Discrete, Dict), and the
//! checks a server runs on what it sends and what it receives.

use serde::{Deserialize, Serialize};

use crate::messages::{Action, ActionType, MetaAction, Observation, Tensor, TensorData};

/// Element types.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum DType {
    /// float32.
    F32,
    /// uint8.
    U8,
    /// int8 (PettingZoo's `action_mask` convention).
    I8,
    /// int64.
    I64,
}

impl DType {
    /// NumPy's name for it: "float32", "uint8", "int8", "int64".
    pub fn numpy_name(self) -> &'static str {
        match self {
            DType::F32 => "float32",
            DType::U8 => "uint8",
            DType::I8 => "int8",
            DType::I64 => "int64",
        }
    }
}

/// A Gymnasium space.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum Space {
    /// `gymnasium.spaces.Box(low, high, shape, dtype)`; low and high hold one bound per
    /// element, row-major.
    Box {
        /// Lower bounds.
        low: Vec<f32>,
        /// Upper bounds.
        high: Vec<f32>,
        /// Shape.
        shape: Vec<u32>,
        /// Element type.
        dtype: DType,
    },
    /// `gymnasium.spaces.Discrete(n, start)`: the integers `start..start + n`.
    Discrete {
        /// Number of actions.
        n: u32,
        /// First action.
        start: i64,
    },
    /// `gymnasium.spaces.Dict`, keys sorted.
    Dict(Vec<(String, Space)>),
}

impl TensorData {
    fn dtype(&self) -> DType {
        match self {
            TensorData::F32(_) => DType::F32,
            TensorData::U8(_) => DType::U8,
            TensorData::I8(_) => DType::I8,
            TensorData::I64(_) => DType::I64,
        }
    }

    fn values(&self) -> Vec<f64> {
        match self {
            TensorData::F32(v) => v.iter().map(|&x| f64::from(x)).collect(),
            TensorData::U8(v) => v.iter().map(|&x| f64::from(x)).collect(),
            TensorData::I8(v) => v.iter().map(|&x| f64::from(x)).collect(),
            TensorData::I64(v) => v.iter().map(|&x| x as f64).collect(),
        }
    }
}

impl Space {
    /// Whether `tensor` has this Box's shape and dtype and every element is finite and
    /// within its bounds. False for any other space.
    pub fn contains_tensor(&self, tensor: &Tensor) -> bool {
        let Space::Box { low, high, shape, dtype } = self else { return false };
        let n = tensor.data.len();
        if &tensor.shape != shape || tensor.data.dtype() != *dtype || low.len() != n || high.len() != n {
            return false;
        }
        tensor
            .data
            .values()
            .iter()
            .zip(low.iter().zip(high))
            .all(|(&x, (&lo, &hi))| x.is_finite() && f64::from(lo) <= x && x <= f64::from(hi))
    }

    /// Whether `observation` belongs to this space (a Box, or a Dict of Boxes with the
    /// same keys in the same order).
    pub fn contains(&self, observation: &Observation) -> bool {
        match (self, observation) {
            (Space::Box { .. }, Observation::Tensor(tensor)) => self.contains_tensor(tensor),
            (Space::Dict(spaces), Observation::Dict(tensors)) => {
                spaces.len() == tensors.len()
                    && spaces
                        .iter()
                        .zip(tensors)
                        .all(|((key, space), (name, tensor))| key == name && space.contains_tensor(tensor))
            }
            _ => false,
        }
    }

    /// Checks an action against this space: a meta action against a Discrete, a
    /// continuous one against a Box of shape `[2]`. The error says which component is
    /// wrong and what the bounds are. The server checks every action so, where it enters
    /// (server/src/env/action.rs); clients check nothing more than the wire needs
    /// (`Action::from_code`, `Action::from_values`), with these same messages.
    pub fn contains_action(&self, action: &Action) -> Result<(), String> {
        match (self, action) {
            (Space::Discrete { .. }, &Action::Meta(choice)) => self.contains_code(i64::from(choice)),
            (Space::Box { .. }, Action::Continuous(values)) => self.contains_values(values),
            (space, action) => Err(format!("a {} action does not fit a {} space", action.kind(), space.kind())),
        }
    }

    /// Whether a Discrete space holds `choice`.
    fn contains_code(&self, choice: i64) -> Result<(), String> {
        let &Space::Discrete { n, start } = self else {
            return Err(format!("a meta action does not fit a {} space", self.kind()));
        };
        let end = start + i64::from(n);
        if (start..end).contains(&choice) {
            Ok(())
        } else {
            Err(format!("meta action {choice} is outside Discrete({n}): use {start}..={}", end - 1))
        }
    }

    /// Whether a Box space of one dimension holds `values`: its size, each finite and
    /// within its bounds.
    fn contains_values(&self, values: &[f32]) -> Result<(), String> {
        let Space::Box { low, high, shape, .. } = self else {
            return Err(format!("a continuous action does not fit a {} space", self.kind()));
        };
        let n = values.len();
        if shape[..] != [n as u32] || low.len() != n || high.len() != n {
            return Err(format!("a continuous action has {n} components, but the space has shape {shape:?}"));
        }
        for (i, ((&x, &lo), &hi)) in values.iter().zip(low).zip(high).enumerate() {
            if !x.is_finite() {
                return Err(format!("component {i} is {x}; it must be a finite number in [{lo}, {hi}]"));
            }
            if !(lo..=hi).contains(&x) {
                return Err(format!("component {i} is {x}, outside [{lo}, {hi}]"));
            }
        }
        Ok(())
    }

    fn kind(&self) -> &'static str {
        match self {
            Space::Box { .. } => "Box",
            Space::Discrete { .. } => "Discrete",
            Space::Dict(_) => "Dict",
        }
    }
}

impl Action {
    fn kind(&self) -> &'static str {
        match self {
            Action::Meta(_) => "meta",
            Action::Continuous(_) => "continuous",
        }
    }

    /// The meta action of a code a client was given as any integer. Refuses only a code
    /// the wire cannot carry (outside `u32`), with the message the server's check gives
    /// (every meta agent's space is `ActionType::Meta.space()`); the server checks the
    /// rest.
    pub fn from_code(code: i64) -> Result<Action, String> {
        u32::try_from(code).map(Action::Meta).map_err(|_| {
            let refused = ActionType::Meta.space().contains_code(code);
            refused.err().unwrap_or_else(|| format!("meta action {code} does not fit the wire's u32"))
        })
    }

    /// The continuous action of the numbers a client was given. Refuses only numbers the
    /// wire cannot carry (not 2 of them), with the message the server's check gives (every
    /// continuous agent's space is `ActionType::Continuous.space()`); the server checks the
    /// rest (finite, within bounds).
    pub fn from_values(values: &[f32]) -> Result<Action, String> {
        <[f32; 2]>::try_from(values).map(Action::Continuous).map_err(|_| {
            let refused = ActionType::Continuous.space().contains_values(values);
            refused.err().unwrap_or_else(|| format!("a continuous action is 2 numbers, not {}", values.len()))
        })
    }
}

impl ActionType {
    /// The action space of an agent acting so: Discrete(`MetaAction::ALL.len()`) for
    /// meta actions; a Box of 2 in [-1, 1] (acceleration, preview offset) for continuous
    /// ones. `EnvSpecs::action_spaces` carries it to clients.
    pub fn space(self) -> Space {
        match self {
            ActionType::Meta => Space::Discrete { n: MetaAction::ALL.len() as u32, start: 0 },
            ActionType::Continuous => {
                Space::Box { low: vec![-1.0; 2], high: vec![1.0; 2], shape: vec![2], dtype: DType::F32 }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn continuous() -> Space {
        Space::Box { low: vec![-6.0, -4.0], high: vec![6.0, 4.0], shape: vec![2], dtype: DType::F32 }
    }

    #[test]
    fn meta_actions_must_lie_in_the_discrete_range() {
        let meta = Space::Discrete { n: 5, start: 0 };
        for choice in 0..5 {
            assert_eq!(meta.contains_action(&Action::Meta(choice)), Ok(()));
        }
        assert_eq!(
            meta.contains_action(&Action::Meta(5)),
            Err("meta action 5 is outside Discrete(5): use 0..=4".into())
        );
        let shifted = Space::Discrete { n: 3, start: 1 };
        assert!(shifted.contains_action(&Action::Meta(0)).unwrap_err().contains("use 1..=3"));
        assert_eq!(shifted.contains_action(&Action::Meta(3)), Ok(()));
    }

    #[test]
    fn continuous_actions_must_be_finite_and_within_bounds() {
        let space = continuous();
        assert_eq!(space.contains_action(&Action::Continuous([6.0, -4.0])), Ok(()));
        assert_eq!(space.contains_action(&Action::Continuous([-0.5, 3.9])), Ok(()));
        assert_eq!(
            space.contains_action(&Action::Continuous([0.0, 4.5])),
            Err("component 1 is 4.5, outside [-4, 4]".into())
        );
        assert_eq!(
            space.contains_action(&Action::Continuous([-6.1, 0.0])),
            Err("component 0 is -6.1, outside [-6, 6]".into())
        );
        let nan = space.contains_action(&Action::Continuous([f32::NAN, 0.0])).unwrap_err();
        assert!(nan.starts_with("component 0 is NaN") && nan.contains("[-6, 6]"), "{nan}");
        let inf = space.contains_action(&Action::Continuous([0.0, f32::NEG_INFINITY])).unwrap_err();
        assert!(inf.starts_with("component 1 is -inf"), "{inf}");
    }

    #[test]
    fn actions_of_the_wrong_type_or_shape_are_refused() {
        let meta = Space::Discrete { n: 5, start: 0 };
        assert_eq!(
            meta.contains_action(&Action::Continuous([0.0, 0.0])),
            Err("a continuous action does not fit a Discrete space".into())
        );
        assert_eq!(
            continuous().contains_action(&Action::Meta(1)),
            Err("a meta action does not fit a Box space".into())
        );
        let three = Space::Box { low: vec![0.0; 3], high: vec![1.0; 3], shape: vec![3], dtype: DType::F32 };
        assert!(three.contains_action(&Action::Continuous([0.0, 0.0])).unwrap_err().contains("shape [3]"));
        // Bounds that do not match the shape never let an action through.
        let short = Space::Box { low: vec![0.0], high: vec![1.0], shape: vec![2], dtype: DType::F32 };
        assert!(short.contains_action(&Action::Continuous([0.5, 9.0])).is_err());
    }

    #[test]
    fn clients_refuse_only_what_the_wire_cannot_carry_with_the_servers_words() {
        assert_eq!(Action::from_code(4), Ok(Action::Meta(4)));
        assert_eq!(Action::from_code(7), Ok(Action::Meta(7)), "the server's to refuse");
        assert_eq!(Action::from_code(-1), Err("meta action -1 is outside Discrete(5): use 0..=4".into()));
        assert_eq!(
            Action::from_code(1 << 40),
            Err("meta action 1099511627776 is outside Discrete(5): use 0..=4".into())
        );
        assert_eq!(Action::from_values(&[0.5, -1.0]), Ok(Action::Continuous([0.5, -1.0])));
        assert_eq!(Action::from_values(&[9.0, f32::NAN]).map(|_| ()), Ok(()), "the server's to refuse");
        assert_eq!(
            Action::from_values(&[0.0; 3]),
            Err("a continuous action has 3 components, but the space has shape [2]".into())
        );
        assert_eq!(
            ActionType::Continuous.space().contains_action(&Action::Continuous([1.5, 0.0])),
            Err("component 0 is 1.5, outside [-1, 1]".into())
        );
        assert_eq!(ActionType::Meta.space(), Space::Discrete { n: 5, start: 0 });
    }

    #[test]
    fn tensors_must_match_shape_dtype_and_bounds() {
        let unit = Space::Box { low: vec![-1.0; 4], high: vec![1.0; 4], shape: vec![2, 2], dtype: DType::F32 };
        let tensor = |data: Vec<f32>| Tensor::new(vec![2, 2], TensorData::F32(data)).unwrap();
        assert!(unit.contains_tensor(&tensor(vec![0.0, 1.0, -1.0, 0.5])));
        assert!(!unit.contains_tensor(&tensor(vec![0.0, 1.5, -1.0, 0.5])));
        assert!(!unit.contains_tensor(&tensor(vec![0.0, f32::NAN, -1.0, 0.5])));
        assert!(!unit.contains_tensor(&Tensor::new(vec![4], TensorData::F32(vec![0.0; 4])).unwrap()), "shape");
        assert!(!unit.contains_tensor(&Tensor::new(vec![2, 2], TensorData::U8(vec![0; 4])).unwrap()), "dtype");
        let mask = Space::Box { low: vec![0.0; 5], high: vec![1.0; 5], shape: vec![5], dtype: DType::I8 };
        let dict = Space::Dict(vec![("action_mask".into(), mask), ("observation".into(), unit)]);
        let observation = |mask: Vec<i8>| {
            Observation::Dict(vec![
                ("action_mask".into(), Tensor::new(vec![5], TensorData::I8(mask)).unwrap()),
                ("observation".into(), tensor(vec![0.0; 4])),
            ])
        };
        assert!(dict.contains(&observation(vec![1, 1, 0, 1, 0])));
        assert!(!dict.contains(&observation(vec![1, 1, 0, 2, 0])));
        assert!(!dict.contains(&Observation::Tensor(tensor(vec![0.0; 4]))));
    }

    #[test]
    fn dtypes_have_numpy_names() {
        let names = [DType::F32, DType::U8, DType::I8, DType::I64].map(DType::numpy_name);
        assert_eq!(names, ["float32", "uint8", "int8", "int64"]);
    }
}

//! Space specs that map one-to-one onto Gymnasium spaces (Box, Discrete, Dict), and the
//! checks a server runs on what it sends and what it receives.

use serde::{Deserialize, Serialize};

use crate::messages::{Action, Observation, Tensor, TensorData};

/// Element types.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum DType {
    /// float32.
    F32,
    /// uint8.
    U8,
    /// int8.
    I8,
    /// int64.
    I64,
}

impl DType {
    /// NumPy's name for it.
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
    /// `gymnasium.spaces.Discrete(n, start)`.
    Discrete {
        /// Number of actions.
        n: u32,
        /// First action.
        start: i64,
    },
    /// `gymnasium.spaces.Dict`, keys sorted.
    Dict(Vec<(String, Space)>),
}

fn values(data: &TensorData) -> Vec<f64> {
    match data {
        TensorData::F32(v) => v.iter().map(|&x| f64::from(x)).collect(),
        TensorData::U8(v) => v.iter().map(|&x| f64::from(x)).collect(),
        TensorData::I8(v) => v.iter().map(|&x| f64::from(x)).collect(),
        TensorData::I64(v) => v.iter().map(|&x| x as f64).collect(),
    }
}

fn dtype_of(data: &TensorData) -> DType {
    match data {
        TensorData::F32(_) => DType::F32,
        TensorData::U8(_) => DType::U8,
        TensorData::I8(_) => DType::I8,
        TensorData::I64(_) => DType::I64,
    }
}

impl Space {
    /// Whether `tensor` has this Box's shape and dtype and lies within its bounds.
    pub fn contains_tensor(&self, tensor: &Tensor) -> bool {
        let Space::Box { low, high, shape, dtype } = self else { return false };
        if &tensor.shape != shape || dtype_of(&tensor.data) != *dtype || tensor.data.len() != low.len() {
            return false;
        }
        values(&tensor.data)
            .iter()
            .zip(low.iter().zip(high))
            .all(|(&x, (&lo, &hi))| x.is_finite() && f64::from(lo) <= x && x <= f64::from(hi))
    }

    /// Whether `observation` belongs to this space (a Box or a Dict of Boxes).
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

    /// Checks an action against this space; the error says which part is wrong.
    pub fn contains_action(&self, action: &Action) -> Result<(), String> {
        match (self, action) {
            (Space::Discrete { n, start }, Action::Meta(choice)) => {
                let choice = i64::from(*choice);
                if (*start..*start + i64::from(*n)).contains(&choice) {
                    Ok(())
                } else {
                    Err(format!(
                        "action {choice} is outside Discrete({n}): use {start}..={}",
                        start + i64::from(*n) - 1
                    ))
                }
            }
            (Space::Box { low, high, shape, .. }, Action::Continuous(values)) => {
                if shape != &[values.len() as u32] {
                    return Err(format!("expected an action of shape {shape:?}"));
                }
                for (i, ((&x, &lo), &hi)) in values.iter().zip(low).zip(high).enumerate() {
                    if !x.is_finite() {
                        return Err(format!("component {i} is {x}; actions must be finite"));
                    }
                    if x < lo || x > hi {
                        return Err(format!("component {i} is {x}, outside [{lo}, {hi}]"));
                    }
                }
                Ok(())
            }
            _ => Err(format!("action {action:?} does not fit the space {self:?}")),
        }
    }
}

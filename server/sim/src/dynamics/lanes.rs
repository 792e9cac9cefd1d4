//! `Lanes<N>`: N numbers, one per vehicle, that every operation treats lane by lane.
//! The model of eq. (1)-(8) is written once over it: with N = 1 it steps one vehicle,
//! with N = 8 a block of vehicles whose element-wise loops the compiler turns into
//! vector instructions of whatever width the calling function was compiled for.
//!
//! Every operation here is one IEEE-754 operation per lane (no fused multiply-add: Rust
//! never contracts `a * b + c`), and comparisons pick lanes with selects, so a vehicle's
//! result is the same bits whatever N is, whatever the vector width, and whatever the
//! other lanes hold.

use std::ops::{Add, Div, Mul, Neg, Sub};

/// N values operated on lane by lane.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Lanes<const N: usize>(pub [f64; N]);

/// A lane-by-lane truth value.
pub type Mask<const N: usize> = [bool; N];

/// Lane i holds `holds(i)`.
#[inline(always)]
pub fn mask<const N: usize>(holds: impl Fn(usize) -> bool) -> Mask<N> {
    let mut mask = [false; N];
    for (i, lane) in mask.iter_mut().enumerate() {
        *lane = holds(i);
    }
    mask
}

impl<const N: usize> Lanes<N> {
    /// The same value in every lane.
    #[inline(always)]
    pub fn splat(x: f64) -> Self {
        Lanes([x; N])
    }

    /// Lane i holds `value(i)`. (Plain loops here, not `std::array::from_fn`: the compiler
    /// must inline all of the model into the vectorised caller, and it left `from_fn` out.)
    #[inline(always)]
    pub fn gather(value: impl Fn(usize) -> f64) -> Self {
        let mut lanes = [0.0; N];
        for (i, lane) in lanes.iter_mut().enumerate() {
            *lane = value(i);
        }
        Lanes(lanes)
    }

    /// Lanes `from..from + N` of a wider `Lanes`.
    #[inline(always)]
    pub fn part<const WIDE: usize>(wide: &Lanes<WIDE>, from: usize) -> Self {
        Self::gather(|i| wide.0[from + i])
    }

    /// Writes these lanes over lanes `from..from + N` of a wider `Lanes`.
    #[inline(always)]
    pub fn write_into<const WIDE: usize>(self, wide: &mut Lanes<WIDE>, from: usize) {
        wide.0[from..from + N].copy_from_slice(&self.0);
    }

    /// `f` of every lane.
    #[inline(always)]
    pub fn map(self, f: impl Fn(f64) -> f64) -> Self {
        Self::gather(|i| f(self.0[i]))
    }

    #[inline(always)]
    fn zip(self, other: Self, f: impl Fn(f64, f64) -> f64) -> Self {
        Self::gather(|i| f(self.0[i], other.0[i]))
    }

    /// Per lane: `if_true` where `mask` holds, `if_false` elsewhere.
    #[inline(always)]
    pub fn select(mask: Mask<N>, if_true: Self, if_false: Self) -> Self {
        Self::gather(|i| if mask[i] { if_true.0[i] } else { if_false.0[i] })
    }

    /// Per lane: whether `self < other`.
    #[inline(always)]
    pub fn lt(self, other: Self) -> Mask<N> {
        mask(|i| self.0[i] < other.0[i])
    }

    /// Per lane: the larger, `other` on a tie (as `f64::max` for the numbers used here).
    #[inline(always)]
    pub fn max(self, other: Self) -> Self {
        Self::select(other.lt(self), self, other)
    }

    /// Per lane: the smaller, `other` on a tie.
    #[inline(always)]
    pub fn min(self, other: Self) -> Self {
        Self::select(self.lt(other), self, other)
    }

    /// Per lane: `self` held within [low, high], as `f64::clamp` does it.
    #[inline(always)]
    pub fn clamp(self, low: Self, high: Self) -> Self {
        let raised = Self::select(self.lt(low), low, self);
        Self::select(high.lt(raised), high, raised)
    }
}

impl<const N: usize> Default for Lanes<N> {
    fn default() -> Self {
        Lanes::splat(0.0)
    }
}

impl<const N: usize> From<f64> for Lanes<N> {
    #[inline(always)]
    fn from(x: f64) -> Self {
        Lanes::splat(x)
    }
}

macro_rules! lane_wise {
    ($trait:ident, $method:ident, $op:tt) => {
        impl<const N: usize> $trait for Lanes<N> {
            type Output = Self;
            #[inline(always)]
            fn $method(self, other: Self) -> Self {
                self.zip(other, |a, b| a $op b)
            }
        }
    };
}

lane_wise!(Add, add, +);
lane_wise!(Sub, sub, -);
lane_wise!(Mul, mul, *);
lane_wise!(Div, div, /);

impl<const N: usize> Neg for Lanes<N> {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        self.map(|x| -x)
    }
}

/// Angles up to this size (rad) take the series of `sin_cos`; larger ones take libm.
/// 0.15: a car's heading against its lane stays below it in a lane change at speed (and
/// its steering angle far below), and there the series' truncation error is below 1e-20.
pub const SERIES_ANGLE: f64 = 0.15;

/// Taylor coefficients of sin x / x and cos x in powers of x²: (-1)^k / (2k+1)! and
/// (-1)^k / (2k)!, to x^11 and x^12.
const SIN: [f64; 6] = [1.0, -1.0 / 6.0, 1.0 / 120.0, -1.0 / 5040.0, 1.0 / 362_880.0, -1.0 / 39_916_800.0];
const COS: [f64; 7] =
    [1.0, -1.0 / 2.0, 1.0 / 24.0, -1.0 / 720.0, 1.0 / 40_320.0, -1.0 / 3_628_800.0, 1.0 / 479_001_600.0];

/// sin and cos of every lane. Within `SERIES_ANGLE` they are the Taylor series (Horner
/// form, within 1 ulp of the exact value), which vectorises; beyond it libm's `sin_cos`,
/// lane by lane. This replaced two libm calls per vehicle and step that were a fifth of
/// the world step's time.
#[inline(always)]
pub fn sin_cos<const N: usize>(x: Lanes<N>) -> (Lanes<N>, Lanes<N>) {
    let x2 = x * x;
    let horner = |coefficients: &[f64]| {
        let (last, rest) = coefficients.split_last().expect("a series has terms");
        rest.iter().rev().fold(Lanes::splat(*last), |sum, &c| Lanes::splat(c) + x2 * sum)
    };
    let (mut sin, mut cos) = (x * horner(&SIN), horner(&COS));
    if !x.0.iter().all(|&angle| in_series(angle)) {
        large_angles(&x.0, &mut sin.0, &mut cos.0);
    }
    (sin, cos)
}

/// Whether `angle` takes the series (not a NaN, which libm answers).
#[inline(always)]
fn in_series(angle: f64) -> bool {
    angle.abs() <= SERIES_ANGLE
}

/// libm for the lanes beyond the series. Out of line and cold: inlined, the compiler
/// computed libm's cos for every lane and selected, a seventh of the world step.
#[cold]
#[inline(never)]
fn large_angles(x: &[f64], sin: &mut [f64], cos: &mut [f64]) {
    for i in 0..x.len() {
        if !in_series(x[i]) {
            (sin[i], cos[i]) = x[i].sin_cos();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn series_sin_cos_is_within_one_ulp_of_libm() {
        for k in -2500..=2500 {
            let x = k as f64 * 0.6e-4 + 1.7e-9;
            let (sin, cos) = sin_cos(Lanes([x]));
            let (exact_sin, exact_cos) = x.sin_cos();
            assert!((sin.0[0] - exact_sin).abs() <= exact_sin.abs() * 2.3e-16, "sin {x}");
            assert!((cos.0[0] - exact_cos).abs() <= 1.2e-16, "cos {x}");
        }
    }

    #[test]
    fn large_angles_take_libm() {
        let x = Lanes([0.3, -1.0, 2.5, 0.1]);
        let (sin, cos) = sin_cos(x);
        for i in 0..3 {
            assert_eq!((sin.0[i], cos.0[i]), x.0[i].sin_cos());
        }
    }

    #[test]
    fn clamp_and_max_pick_lanes_as_f64_does() {
        let x = Lanes([-2.0, 0.5, 3.0, 1.0]);
        assert_eq!(x.clamp(Lanes::splat(0.0), Lanes::splat(1.0)).0, [0.0, 0.5, 1.0, 1.0]);
        assert_eq!(x.max(Lanes::splat(0.7)).0, [0.7, 0.7, 3.0, 1.0]);
    }
}

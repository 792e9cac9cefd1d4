//! Driving styles as the AV sees them: Table III's cost weights (w_ds, w_rc, w_pe of
//! eq. 9) per style, next to Table I's driver parameters (which `dynamics` owns, because
//! the integrated model of eq. 1–8 needs them too).

use serde::{Deserialize, Serialize};

use crate::dynamics::{DriverParams, Style};

/// The weights of eq. (9) for one style: how much the three costs count.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CostWeights {
    /// w_ds, driving safety (dimensionless). Table III: 0.1 / 0.5 / 0.7.
    pub safety: f64,
    /// w_rc, ride comfort (dimensionless). Table III: 0.1 / 0.3 / 0.2.
    pub comfort: f64,
    /// w_pe, travel efficiency (dimensionless). Table III: 0.8 / 0.2 / 0.1.
    pub efficiency: f64,
}

impl CostWeights {
    /// Table III's column for `style` (aggressive / normal / conservative).
    pub fn for_style(style: Style) -> CostWeights {
        let (safety, comfort, efficiency) = match style {
            Style::Aggressive => (0.1, 0.1, 0.8),
            Style::Normal => (0.5, 0.3, 0.2),
            Style::Conservative => (0.7, 0.2, 0.1),
        };
        CostWeights { safety, comfort, efficiency }
    }
}

impl Default for CostWeights {
    fn default() -> Self {
        CostWeights::for_style(Style::Normal)
    }
}

/// Everything a style fixes: Table I for the driver model, Table III for the costs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StyleProfile {
    /// Table I (with the K_s schedule chosen in `dynamics`).
    pub driver: DriverParams,
    /// Table III.
    pub weights: CostWeights,
}

impl StyleProfile {
    /// The profile of `style`.
    pub fn for_style(style: Style) -> StyleProfile {
        StyleProfile { driver: DriverParams::for_style(style), weights: CostWeights::for_style(style) }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table_iii_columns_sum_to_one_and_order_the_styles() {
        for style in Style::ALL {
            let w = CostWeights::for_style(style);
            assert!((w.safety + w.comfort + w.efficiency - 1.0).abs() < 1e-12, "{style:?}");
        }
        let [a, n, c] = Style::ALL.map(CostWeights::for_style);
        assert!(a.efficiency > n.efficiency && n.efficiency > c.efficiency);
        assert!(a.safety < n.safety && n.safety < c.safety);
        assert_eq!((n.safety, n.comfort, n.efficiency), (0.5, 0.3, 0.2));
        let profile = StyleProfile::for_style(Style::Conservative);
        assert_eq!((profile.driver.delay, profile.weights.safety), (0.24, 0.7));
    }
}

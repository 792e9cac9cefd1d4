//! The colours of every picture of a world, written once: the server's `RgbArray` frames
//! and the Python package's recordings and viewer paint with these (the extension hands
//! them to Python as `_core.PALETTE`). Learners are green, the game-theoretic AV blue by
//! style (darker is bolder), IDM cars yellow, a crashed car red.

use crate::messages::Style;

/// An sRGB colour.
pub type Rgb = [u8; 3];

/// Off the road.
pub const GRASS: Rgb = [60, 110, 60];
/// The road.
pub const ASPHALT: Rgb = [90, 90, 90];
/// Lane lines.
pub const MARKING: Rgb = [235, 235, 235];
/// A learner, whoever drives it.
pub const LEARNER: Rgb = [50, 200, 80];
/// An IDM car.
pub const IDM: Rgb = [230, 200, 60];
/// A car that crashed, and a collision.
pub const CRASHED: Rgb = [220, 40, 40];
/// A car whose episode ended otherwise (off the road, past its lane's end).
pub const GONE: Rgb = [150, 150, 150];
/// Where a lane ends: its marker's dark squares (its light ones are `ENDED`).
pub const LANE_END: Rgb = [200, 30, 30];
/// An end that is no crash, and the lane-end marker's light squares.
pub const ENDED: Rgb = [250, 250, 250];
/// Text.
pub const TEXT: Rgb = [255, 255, 255];
/// Behind the end reason written on a frame.
pub const BANNER: Rgb = [150, 20, 20];
/// An explained decision's own predicted path.
pub const PLAN: Rgb = [250, 140, 30];
/// The path an explained decision predicted for the other player.
pub const PREDICTION: Rgb = [200, 80, 220];

/// A game-theoretic car of `style`.
pub const fn gt(style: Style) -> Rgb {
    match style {
        Style::Aggressive => [40, 70, 200],
        Style::Normal => [60, 120, 235],
        Style::Conservative => [120, 190, 250],
    }
}

/// Every colour but the game-theoretic cars' (`gt`), by name, for clients.
pub const NAMED: [(&str, Rgb); 13] = [
    ("grass", GRASS),
    ("asphalt", ASPHALT),
    ("marking", MARKING),
    ("learner", LEARNER),
    ("idm", IDM),
    ("crashed", CRASHED),
    ("gone", GONE),
    ("lane_end", LANE_END),
    ("ended", ENDED),
    ("text", TEXT),
    ("banner", BANNER),
    ("plan", PLAN),
    ("prediction", PREDICTION),
];

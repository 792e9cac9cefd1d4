//! Pictures of the road around a vehicle, drawn on the server so every client gets the
//! same frame: `rgb` (top-down in world coordinates, north up, the road drawn from its
//! own geometry so a bend is a bend; H x W x 3 uint8, with the simulated time, the
//! followed car's name and speed, its end reason once its episode ended, lane ends
//! marked, and a legend of who drives which colour, text scaled with the frame) and
//! `ansi` (lanes as rows of text). The window follows one vehicle, the first learner
//! unless the client names another. The colours are the protocol's `palette`, as the
//! recordings': learners green, game-theoretic cars blue by style, IDM cars yellow,
//! crashed red; the followed car has a white outline.

use arena_protocol::palette::{self, ASPHALT, BANNER, CRASHED, GRASS, IDM, LEARNER, MARKING, Rgb, TEXT};
use arena_protocol::{EndReason, Frame, Style};

use arena_sim::{Driver, Ending, LaneId, Status, Vehicle, VehicleId, World};

use super::style_of;

/// Metres of road across the width of an `rgb` frame, unless the env's `render_window`
/// says otherwise.
const RGB_WINDOW: u32 = 120;
/// The window's bounds (m): a frame always shows a car whole, and a road of the longest
/// sections fits.
const WINDOWS: std::ops::RangeInclusive<u32> = 10..=10_000;
/// The most pixels a metre of road may take in an asked window: a car's box costs its area
/// in pixels, so this bounds a frame's cost whatever the window (the default window on a
/// 2300 x 2300 frame, about the largest a reply carries, has 19; docs/reliability.md
/// measures that). The default window is never refused, however wide the frame.
const MAX_PIXELS_PER_METRE: u32 = 20;
/// Frame height (pixels) per step of text size: text is drawn in a 3 x 5 font, each font
/// pixel `height / TEXT_HEIGHT_PER_SIZE` pixels square (at least 1), so a legend stays
/// legible at 600 x 1200 and fits at 60 x 120.
const TEXT_HEIGHT_PER_SIZE: u32 = 150;
/// Length of the lane-end marker (m), painted just before the end across the ending lane.
const LANE_END_MARKER: f64 = 1.5;
/// Pixels on a side of the square patches the ground is painted in: each patch first
/// finds the road's sections near it (`Road::nearby`), then paints its pixels from those.
const TILE: u32 = 8;
/// The most sections one patch paints from: a road that does not lie over itself has one
/// to three near a patch; one that passes it more often is painted from the pass nearest
/// the patch's centre, so a picture's cost is bounded whatever road a client sends.
const SECTIONS_PER_TILE: usize = 8;
/// Width of the followed car's outline (m).
const OUTLINE: f64 = 0.35;
/// Metres of road per character in `ansi`, and characters each side of the focus.
const ANSI_METRES_PER_CHAR: f64 = 2.0;
const ANSI_HALF_WIDTH: usize = 40;

/// The lane-end marker's two colours, in a checker.
const LANE_END: [Rgb; 2] = [palette::LANE_END, palette::ENDED];

/// The legend, in the order drawn: each colour and its label (the game-theoretic cars'
/// swatch is the normal style's).
const LEGEND: [(Rgb, &str); 5] = [
    (LEARNER, "LEARNER"),
    (palette::gt(Style::Normal), "GT"),
    (IDM, "IDM"),
    (CRASHED, "CRASH"),
    (LANE_END[0], "LANE END"),
];

/// Vehicle `id`'s colour: by its driver, a game-theoretic car's by its style.
fn colour(world: &World, id: VehicleId) -> Rgb {
    let vehicle = world.vehicle(id);
    match (vehicle.status, &vehicle.driver) {
        (Status::Crashed, _) => CRASHED,
        (_, Driver::Agent(_)) => LEARNER,
        (_, Driver::Gt(_)) => palette::gt(style_of(world.style(id))),
        (_, Driver::Idm) => IDM,
    }
}

/// The metres across the width of frames `width` pixels wide: `asked` (the env's
/// `render_window`) if it is within `WINDOWS` and leaves at most `MAX_PIXELS_PER_METRE`
/// (or is at least `RGB_WINDOW`), else what is wrong with it; `RGB_WINDOW` if none was
/// asked.
pub fn window(asked: Option<u32>, width: u32) -> Result<f64, String> {
    let Some(metres) = asked else { return Ok(f64::from(RGB_WINDOW)) };
    if !WINDOWS.contains(&metres) {
        return Err(format!("render_window {metres} must be within {}..={} (m)", WINDOWS.start(), WINDOWS.end()));
    }
    let least = width.div_ceil(MAX_PIXELS_PER_METRE).min(RGB_WINDOW);
    if metres < least {
        return Err(format!(
            "render_window {metres} makes frames {width} pixels wide draw more than {MAX_PIXELS_PER_METRE} pixels a \
             metre; ask for at least {least} m, or smaller frames"
        ));
    }
    Ok(f64::from(metres))
}

/// The followed vehicle's (s, d), or the first vehicle's s on the reference line.
fn focus_point(world: &World, focus: Option<VehicleId>) -> (f64, f64) {
    match focus {
        Some(id) => (world.vehicle(id).state.s, world.vehicle(id).state.d),
        None => (world.vehicles().first().map_or(0.0, |v| v.state.s), 0.0),
    }
}

/// The end reason shown for a vehicle whose episode ended in the world, by its protocol
/// name (`EndReason::name`; a learner that ran out of time is the env's to name).
pub fn ending_name(ending: Ending) -> &'static str {
    match ending {
        Ending::Collision => EndReason::Collision,
        Ending::LaneEnd => EndReason::LaneEnd,
        Ending::OffRoad => EndReason::OffRoad,
        Ending::RoadEnd => EndReason::RoadEnd,
    }
    .name()
}

/// The metres-to-pixels map of a frame centred on a global point, north up.
#[derive(Clone, Copy)]
struct Camera {
    centre: (f64, f64),
    /// Pixels per metre.
    scale: f64,
    size: (u32, u32),
}

impl Camera {
    /// The global (x, y) at the centre of pixel (row, col).
    fn world_at(&self, row: u32, col: u32) -> (f64, f64) {
        let (height, width) = self.size;
        (
            self.centre.0 + (col as f64 + 0.5 - width as f64 / 2.0) / self.scale,
            self.centre.1 - (row as f64 + 0.5 - height as f64 / 2.0) / self.scale,
        )
    }

    /// The pixel (row, col) a global point falls in, as floats (may lie outside).
    fn pixel_of(&self, (x, y): (f64, f64)) -> (f64, f64) {
        let (height, width) = self.size;
        (height as f64 / 2.0 - (y - self.centre.1) * self.scale, width as f64 / 2.0 + (x - self.centre.0) * self.scale)
    }
}

/// A top-down picture in world coordinates, `size` = (height, width) in pixels and
/// `window` metres across (`window`'s), following `focus`; `end` is the followed car's
/// end reason once its episode ended.
pub fn rgb(
    world: &World,
    focus: Option<VehicleId>,
    end: Option<&str>,
    (height, width): (u32, u32),
    window: f64,
) -> Frame {
    let (s0, d0) = focus_point(world, focus);
    let centre = world.road().to_global(s0, d0, 0.0);
    let camera = Camera { centre: (centre.x, centre.y), scale: width as f64 / window, size: (height, width) };
    let mut pixels = vec![0u8; (height * width * 3) as usize];
    let (road, pixel) = (world.road(), 1.0 / camera.scale);
    // A point twice the road's width from its reference line is grass wherever it projects.
    let reach = 2.0 * road.lane_width() * road.lane_count() as f64 + 1.0;
    for (top, left) in (0..height)
        .step_by(TILE as usize)
        .flat_map(|top| (0..width).step_by(TILE as usize).map(move |left| (top, left)))
    {
        let (rows, cols) = (top..(top + TILE).min(height), left..(left + TILE).min(width));
        let centre = camera.world_at(top + TILE / 2, left + TILE / 2);
        let nearby = road.nearby(centre.0, centre.1, TILE as f64 * pixel, reach, SECTIONS_PER_TILE);
        for row in rows {
            for col in cols.clone() {
                let at = ((row * width + col) * 3) as usize;
                let (x, y) = camera.world_at(row, col);
                let paint = match road.to_frenet_among(&nearby, x, y, reach) {
                    Some(frenet) => ground(world, frenet, pixel),
                    None => GRASS,
                };
                pixels[at..at + 3].copy_from_slice(&paint);
            }
        }
    }
    let mut canvas = Canvas { pixels: &mut pixels, height, width, size: (height / TEXT_HEIGHT_PER_SIZE).max(1) };
    let reach = window.hypot(height as f64 / camera.scale) / 2.0 + 5.0;
    // A car that left the road stays where it stopped; one that drove off its end is gone.
    let shown = |v: &&Vehicle| v.status != Status::Exited;
    for (i, vehicle) in world.vehicles().iter().enumerate().filter(|(_, v)| shown(v)) {
        let pose = world.road().to_global(vehicle.state.s, vehicle.state.d, vehicle.state.heading);
        if (pose.x - camera.centre.0).hypot(pose.y - camera.centre.1) > reach {
            continue;
        }
        let (half_length, half_width) = (world.vehicle_params().length / 2.0, world.vehicle_params().width / 2.0);
        if focus == Some(VehicleId(i as u32)) {
            draw_box(
                &mut canvas,
                &camera,
                (pose.x, pose.y, pose.heading),
                (half_length + OUTLINE, half_width + OUTLINE),
                TEXT,
            );
        }
        draw_box(
            &mut canvas,
            &camera,
            (pose.x, pose.y, pose.heading),
            (half_length, half_width),
            colour(world, VehicleId(i as u32)),
        );
    }
    caption(&mut canvas, world, focus, end);
    Frame::Rgb { height, width, pixels }
}

/// The paint of the ground at (s, d), the nearest point of the reference line to a
/// pixel: grass, asphalt, a lane line or a lane-end marker. `pixel` is a pixel's size in
/// metres.
fn ground(world: &World, (s, d): (f64, f64), pixel: f64) -> Rgb {
    let road = world.road();
    // The nearest point of the reference line is clamped to the road: a point before its
    // start or past its end projects onto an end exactly, and is not road.
    if s <= 0.0 || s >= road.length() || !road.contains(s, d) {
        return GRASS;
    }
    if is_marking(world, s, d, pixel) {
        return MARKING;
    }
    let lane = road.nearest_lane(d);
    let end = road.lane_end(lane);
    if end < road.length() && (end - LANE_END_MARKER..=end).contains(&s) {
        let checker = ((s - end) / 0.5).floor() as i64 + ((d - road.lane_center(lane)) / 0.5).floor() as i64;
        return LANE_END[checker.rem_euclid(2) as usize];
    }
    ASPHALT
}

/// The time, the followed car and its speed top left; its end reason on a banner top
/// right; the legend along the bottom.
fn caption(canvas: &mut Canvas, world: &World, focus: Option<VehicleId>, end: Option<&str>) {
    let k = canvas.size;
    let mut text = format!("T {:.1} S", world.time());
    if let Some(id) = focus {
        text += &format!("  {} {:.1} M/S", world.name(id), world.vehicle(id).state.vx);
    }
    canvas.text(2 * k, 2 * k, &text, TEXT);
    if let Some(end) = end {
        // Written as words: `lane_end` is LANE END (the font has capitals only).
        let label = format!("END: {}", end.replace('_', " "));
        let width = canvas.text_width(&label);
        let x = canvas.width.saturating_sub(width + 4 * k);
        canvas.rect(x, k, width + 3 * k, 7 * k, BANNER);
        canvas.text(x + 2 * k, 2 * k, &label, TEXT);
    }
    let y = canvas.height.saturating_sub(7 * k);
    let mut x = 2 * k;
    for (paint, label) in LEGEND {
        canvas.rect(x, y, 5 * k, 5 * k, paint);
        if paint == LANE_END[0] {
            // The marker's checker, so it is not read as a crash.
            for (dx, dy) in (0..5).flat_map(|dx| (0..5).map(move |dy| (dx, dy))).filter(|(dx, dy)| (dx + dy) % 2 == 1) {
                canvas.rect(x + dx * k, y + dy * k, k, k, LANE_END[1]);
            }
        }
        x = canvas.text(x + 7 * k, y, label, TEXT) + 6 * k;
    }
}

/// Paints an oriented box (centre x, y and heading, half length and width, metres).
fn draw_box(canvas: &mut Canvas, camera: &Camera, (x, y, heading): (f64, f64, f64), half: (f64, f64), paint: Rgb) {
    let (row, col) = camera.pixel_of((x, y));
    let reach = (half.0 + half.1) * camera.scale;
    let rows = (row - reach).floor().max(0.0) as u32..(row + reach).ceil().clamp(0.0, canvas.height as f64) as u32;
    let cols = (col - reach).floor().max(0.0) as u32..(col + reach).ceil().clamp(0.0, canvas.width as f64) as u32;
    let (sin, cos) = heading.sin_cos();
    for r in rows {
        for c in cols.clone() {
            let (px, py) = camera.world_at(r, c);
            let (dx, dy) = (px - x, py - y);
            if (dx * cos + dy * sin).abs() <= half.0 && (-dx * sin + dy * cos).abs() <= half.1 {
                canvas.put(c, r, paint);
            }
        }
    }
}

/// Whether (s, d) lies on a painted line: a dashed line between two lanes that both go
/// on at s, a solid one where only one of the two does (a road edge, or the edge left
/// where a lane has ended).
pub(super) fn is_marking(world: &World, s: f64, d: f64, pixel: f64) -> bool {
    let road = world.road();
    let w = road.lane_width();
    let boundary = (d / w - 0.5).round();
    if (d - (boundary + 0.5) * w).abs() >= pixel.max(0.12) {
        return false;
    }
    // The boundary between lane `left` (above) and `left + 1` (below).
    let left = -boundary as i64 - 1;
    let open = |lane: i64| road.has_lane(lane) && s <= road.lane_end(LaneId(lane as u32));
    match (open(left), open(left + 1)) {
        (true, true) => (s / 3.0).rem_euclid(2.0) < 1.0,
        (true, false) | (false, true) => true,
        (false, false) => false,
    }
}

/// An RGB frame to draw text and boxes on.
struct Canvas<'a> {
    pixels: &'a mut [u8],
    height: u32,
    width: u32,
    /// Pixels per font pixel.
    size: u32,
}

impl Canvas<'_> {
    fn put(&mut self, x: u32, y: u32, paint: Rgb) {
        if x < self.width && y < self.height {
            let at = ((y * self.width + x) * 3) as usize;
            self.pixels[at..at + 3].copy_from_slice(&paint);
        }
    }

    fn rect(&mut self, x: u32, y: u32, w: u32, h: u32, paint: Rgb) {
        for row in y..y + h {
            for col in x..x + w {
                self.put(col, row, paint);
            }
        }
    }

    /// Writes `text` in a 3 x 5 font, each font pixel `size` pixels square, from (x, y);
    /// returns the x after it.
    fn text(&mut self, mut x: u32, y: u32, text: &str, paint: Rgb) -> u32 {
        let k = self.size;
        for c in text.chars() {
            let glyph = glyph(c);
            for (row, bits) in glyph.iter().enumerate() {
                for col in 0..3 {
                    if bits & (0b100 >> col) != 0 {
                        self.rect(x + col * k, y + row as u32 * k, k, k, paint);
                    }
                }
            }
            x += 4 * k;
        }
        x
    }

    /// The width `text` takes (pixels).
    fn text_width(&self, text: &str) -> u32 {
        4 * self.size * text.chars().count() as u32
    }
}

/// Rows of a 3 x 5 glyph, top first, leftmost pixel the highest of 3 bits.
fn glyph(c: char) -> [u8; 5] {
    match c.to_ascii_uppercase() {
        '0' | 'O' => [7, 5, 5, 5, 7],
        '1' => [2, 6, 2, 2, 7],
        '2' => [7, 1, 7, 4, 7],
        '3' => [7, 1, 7, 1, 7],
        '4' => [5, 5, 7, 1, 1],
        '5' | 'S' => [7, 4, 7, 1, 7],
        '6' => [7, 4, 7, 5, 7],
        '7' => [7, 1, 1, 1, 1],
        '8' => [7, 5, 7, 5, 7],
        '9' => [7, 5, 7, 1, 7],
        '.' => [0, 0, 0, 0, 2],
        ':' => [0, 2, 0, 2, 0],
        '/' => [1, 1, 2, 4, 4],
        '-' => [0, 0, 7, 0, 0],
        '_' => [0, 0, 0, 0, 7],
        'A' => [2, 5, 7, 5, 5],
        'B' => [6, 5, 6, 5, 6],
        'C' => [7, 4, 4, 4, 7],
        'D' => [6, 5, 5, 5, 6],
        'E' => [7, 4, 6, 4, 7],
        'F' => [7, 4, 6, 4, 4],
        'G' => [7, 4, 5, 5, 7],
        'H' => [5, 5, 7, 5, 5],
        'I' => [7, 2, 2, 2, 7],
        'J' => [1, 1, 1, 5, 7],
        'K' => [5, 5, 6, 5, 5],
        'L' => [4, 4, 4, 4, 7],
        'M' => [5, 7, 7, 5, 5],
        'N' => [6, 5, 5, 5, 5],
        'P' => [7, 5, 7, 4, 4],
        'Q' => [7, 5, 5, 7, 1],
        'R' => [6, 5, 6, 5, 5],
        'T' => [7, 2, 2, 2, 2],
        'U' => [5, 5, 5, 5, 7],
        'V' => [5, 5, 5, 5, 2],
        'W' => [5, 5, 7, 7, 5],
        'X' => [5, 5, 2, 5, 5],
        'Y' => [5, 5, 2, 2, 2],
        'Z' => [7, 1, 2, 4, 7],
        _ => [0; 5],
    }
}

/// Lanes as rows of text: `@` learners, `G` game-theoretic cars, `>` IDM cars, `X`
/// crashed cars; a lane that has ended is blank.
pub fn ansi(world: &World, focus: Option<VehicleId>) -> String {
    let (s0, _) = focus_point(world, focus);
    let columns = 2 * ANSI_HALF_WIDTH + 1;
    let s_at = |col: usize| s0 + (col as f64 - ANSI_HALF_WIDTH as f64) * ANSI_METRES_PER_CHAR;
    let mut rows: Vec<Vec<char>> = (0..world.road().lane_count())
        .map(|lane| {
            let end = world.road().lane_end(LaneId(lane as u32));
            (0..columns).map(|col| if s_at(col) > end { ' ' } else { '.' }).collect()
        })
        .collect();
    for vehicle in world.vehicles().iter().filter(|v| v.on_road()) {
        let col = ((vehicle.state.s - s0) / ANSI_METRES_PER_CHAR).round() + ANSI_HALF_WIDTH as f64;
        if !(0.0..columns as f64).contains(&col) {
            continue;
        }
        let lane = world.road().nearest_lane(vehicle.state.d).0 as usize;
        rows[lane][col as usize] = match (vehicle.status, &vehicle.driver) {
            (Status::Crashed, _) => 'X',
            (_, Driver::Agent(_)) => '@',
            (_, Driver::Gt(_)) => 'G',
            (_, Driver::Idm) => '>',
        };
    }
    let rule: String = "-".repeat(columns);
    let mut text = format!("t = {:6.1} s", world.time());
    if let Some(id) = focus {
        let v = world.vehicle(id);
        text += &format!(
            "   {}: lane {}, {:5.1} m/s, s = {:7.1} m",
            world.name(id),
            world.road().nearest_lane(v.state.d).0,
            v.state.vx,
            v.state.s
        );
    }
    text.push('\n');
    text += &rule;
    for row in rows {
        text.push('\n');
        text.extend(row);
        text.push('\n');
        text += &rule;
    }
    text += "\n@ learner   G game-theoretic   > IDM   X crashed\n";
    text
}

//! Pictures of the road around an agent, drawn on the server so every client gets the
//! same frame: `rgb` (top-down, the road straightened into its Frenet frame, H x W x 3
//! uint8, with the simulated time, the focus car's speed and a legend of who drives
//! which colour) and `ansi` (lanes as rows of text). The window follows the focus
//! vehicle. Learners are green, game-theoretic cars blue, IDM cars yellow, crashed red.

use arena_protocol::Frame;

use arena_sim::{Driver, Status, Vehicle, VehicleId, World};

/// Metres of road shown ahead of and behind the focus vehicle in `rgb`.
const RGB_HALF_WINDOW: f64 = 60.0;
/// Metres of road per character in `ansi`, and characters each side of the focus.
const ANSI_METRES_PER_CHAR: f64 = 2.0;
const ANSI_HALF_WIDTH: usize = 40;

const GRASS: [u8; 3] = [60, 110, 60];
const ASPHALT: [u8; 3] = [90, 90, 90];
const MARKING: [u8; 3] = [235, 235, 235];
const LEARNER: [u8; 3] = [50, 200, 80];
const GT: [u8; 3] = [60, 120, 235];
const IDM: [u8; 3] = [230, 200, 60];
const CRASHED: [u8; 3] = [220, 40, 40];
const TEXT: [u8; 3] = [255, 255, 255];

/// The legend, in the order drawn: each colour and its label.
const LEGEND: [([u8; 3], &str); 4] = [(LEARNER, "LEARNER"), (GT, "GT"), (IDM, "IDM"), (CRASHED, "CRASH")];

fn colour(vehicle: &Vehicle) -> [u8; 3] {
    match (vehicle.status, &vehicle.driver) {
        (Status::Crashed, _) => CRASHED,
        (_, Driver::Agent(_)) => LEARNER,
        (_, Driver::Gt(_)) => GT,
        (_, Driver::Idm) => IDM,
    }
}

fn focus_point(world: &World, focus: Option<VehicleId>) -> (f64, f64) {
    match focus {
        Some(id) => (world.vehicle(id).state.s, world.vehicle(id).state.d),
        None => (world.vehicles().first().map_or(0.0, |v| v.state.s), 0.0),
    }
}

/// A top-down picture, `size` = (height, width) in pixels.
pub fn rgb(world: &World, focus: Option<VehicleId>, (height, width): (u32, u32)) -> Frame {
    let (s0, _) = focus_point(world, focus);
    let scale = width as f64 / (2.0 * RGB_HALF_WINDOW);
    let road_width = world.road().lane_width() * world.road().lane_count() as f64;
    let top = world.road().lane_width() / 2.0 + (height as f64 / scale - road_width) / 2.0;
    let to_frenet =
        |row: u32, col: u32| (s0 + (col as f64 + 0.5) / scale - RGB_HALF_WINDOW, top - (row as f64 + 0.5) / scale);
    let mut pixels = vec![0u8; (height * width * 3) as usize];
    for row in 0..height {
        for col in 0..width {
            let (s, d) = to_frenet(row, col);
            let mut paint = if world.road().contains(s, d) { ASPHALT } else { GRASS };
            if paint == ASPHALT && is_marking(world, s, d, 1.0 / scale) {
                paint = MARKING;
            }
            let at = ((row * width + col) * 3) as usize;
            pixels[at..at + 3].copy_from_slice(&paint);
        }
    }
    for vehicle in world.vehicles().iter().filter(|v| v.on_road() && (v.state.s - s0).abs() < RGB_HALF_WINDOW + 5.0) {
        draw_vehicle(world, vehicle, &mut pixels, (height, width), scale, (s0 - RGB_HALF_WINDOW, top));
    }
    let mut canvas = Canvas { pixels: &mut pixels, height, width };
    let caption = match focus {
        Some(id) => format!("T {:.1} S  {:.1} M/S", world.time(), world.vehicle(id).state.vx),
        None => format!("T {:.1} S", world.time()),
    };
    canvas.text(2, 2, &caption, TEXT);
    let mut x = 2;
    for (paint, label) in LEGEND {
        canvas.rect(x, height.saturating_sub(8), 5, 5, paint);
        x = canvas.text(x + 7, height.saturating_sub(8), label, TEXT) + 6;
    }
    Frame::Rgb { height, width, pixels }
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
    let open = |lane: i64| road.has_lane(lane) && s <= road.lane_end(arena_sim::LaneId(lane as u32));
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
}

impl Canvas<'_> {
    fn put(&mut self, x: u32, y: u32, paint: [u8; 3]) {
        if x < self.width && y < self.height {
            let at = ((y * self.width + x) * 3) as usize;
            self.pixels[at..at + 3].copy_from_slice(&paint);
        }
    }

    fn rect(&mut self, x: u32, y: u32, w: u32, h: u32, paint: [u8; 3]) {
        for row in y..y + h {
            for col in x..x + w {
                self.put(col, row, paint);
            }
        }
    }

    /// Writes `text` in a 3 x 5 pixel font from (x, y); returns the x after it.
    fn text(&mut self, mut x: u32, y: u32, text: &str, paint: [u8; 3]) -> u32 {
        for c in text.chars() {
            let glyph = glyph(c);
            for (row, bits) in glyph.iter().enumerate() {
                for col in 0..3 {
                    if bits & (0b100 >> col) != 0 {
                        self.put(x + col, y + row as u32, paint);
                    }
                }
            }
            x += 4;
        }
        x
    }
}

/// Rows of a 3 x 5 glyph, top first, leftmost pixel the highest of 3 bits.
fn glyph(c: char) -> [u8; 5] {
    match c.to_ascii_uppercase() {
        '0' => [7, 5, 5, 5, 7],
        '1' => [2, 6, 2, 2, 7],
        '2' => [7, 1, 7, 4, 7],
        '3' => [7, 1, 7, 1, 7],
        '4' => [5, 5, 7, 1, 1],
        '5' => [7, 4, 7, 1, 7],
        '6' => [7, 4, 7, 5, 7],
        '7' => [7, 1, 1, 1, 1],
        '8' => [7, 5, 7, 5, 7],
        '9' => [7, 5, 7, 1, 7],
        '.' => [0, 0, 0, 0, 2],
        '/' => [1, 1, 2, 4, 4],
        '-' => [0, 0, 7, 0, 0],
        'A' => [2, 5, 7, 5, 5],
        'C' => [7, 4, 4, 4, 7],
        'D' => [6, 5, 5, 5, 6],
        'E' => [7, 4, 6, 4, 7],
        'G' => [7, 4, 5, 5, 7],
        'H' => [5, 5, 7, 5, 5],
        'I' => [7, 2, 2, 2, 7],
        'L' => [4, 4, 4, 4, 7],
        'M' => [5, 7, 7, 5, 5],
        'N' => [6, 5, 5, 5, 5],
        'R' => [6, 5, 6, 5, 5],
        'S' => [7, 4, 7, 1, 7],
        'T' => [7, 2, 2, 2, 2],
        _ => [0; 5],
    }
}

fn draw_vehicle(
    world: &World,
    vehicle: &Vehicle,
    pixels: &mut [u8],
    (height, width): (u32, u32),
    scale: f64,
    (s_left, top): (f64, f64),
) {
    let (half_length, half_width) = (world.vehicle_params().length / 2.0, world.vehicle_params().width / 2.0);
    let (sin, cos) = vehicle.state.heading.sin_cos();
    let reach = half_length + half_width;
    let col_range = ((vehicle.state.s - reach - s_left) * scale).floor().max(0.0) as u32
        ..((vehicle.state.s + reach - s_left) * scale).ceil().clamp(0.0, width as f64) as u32;
    let row_range = ((top - vehicle.state.d - reach) * scale).floor().max(0.0) as u32
        ..((top - vehicle.state.d + reach) * scale).ceil().clamp(0.0, height as f64) as u32;
    let paint = colour(vehicle);
    for row in row_range {
        for col in col_range.clone() {
            let ds = s_left + (col as f64 + 0.5) / scale - vehicle.state.s;
            let dd = top - (row as f64 + 0.5) / scale - vehicle.state.d;
            let (along, across) = (ds * cos + dd * sin, -ds * sin + dd * cos);
            if along.abs() <= half_length && across.abs() <= half_width {
                let at = ((row * width + col) * 3) as usize;
                pixels[at..at + 3].copy_from_slice(&paint);
            }
        }
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
            let end = world.road().lane_end(arena_sim::LaneId(lane as u32));
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
            v.name,
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

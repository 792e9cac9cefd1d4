//! Pictures of the road around an agent, drawn on the server so every client gets the
//! same frame: `rgb` (top-down, the road straightened into its Frenet frame, H x W x 3
//! uint8) and `ansi` (lanes as rows of text). The window follows the focus vehicle.

use arena_protocol::Frame;

use arena_sim::world::{Driver, Status, Vehicle, VehicleId, World};

/// Metres of road shown ahead of and behind the focus vehicle in `rgb`.
const RGB_HALF_WINDOW: f64 = 60.0;
/// Metres of road per character in `ansi`, and characters each side of the focus.
const ANSI_METRES_PER_CHAR: f64 = 2.0;
const ANSI_HALF_WIDTH: usize = 40;

const GRASS: [u8; 3] = [60, 110, 60];
const ASPHALT: [u8; 3] = [90, 90, 90];
const MARKING: [u8; 3] = [235, 235, 235];

fn colour(vehicle: &Vehicle) -> [u8; 3] {
    match (vehicle.status, &vehicle.driver) {
        (Status::Crashed, _) => [220, 40, 40],
        (_, Driver::Agent(_)) => [50, 200, 80],
        _ => [230, 200, 60],
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
    Frame::Rgb { height, width, pixels }
}

fn is_marking(world: &World, s: f64, d: f64, pixel: f64) -> bool {
    let w = world.road().lane_width();
    let boundary = (d / w - 0.5).round();
    let near = (d - (boundary + 0.5) * w).abs() < pixel.max(0.12);
    let outer = boundary >= 0.0 || boundary <= -(world.road().lane_count() as f64);
    near && (outer || (s / 3.0).rem_euclid(2.0) < 1.0)
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

/// Lanes as rows of text: `@` learners, `>` other cars, `X` crashed cars; `|` marks
/// where a lane ends.
pub fn ansi(world: &World, focus: Option<VehicleId>) -> String {
    let (s0, _) = focus_point(world, focus);
    let columns = 2 * ANSI_HALF_WIDTH + 1;
    let s_at = |col: usize| s0 + (col as f64 - ANSI_HALF_WIDTH as f64) * ANSI_METRES_PER_CHAR;
    let mut rows: Vec<Vec<char>> = (0..world.road().lane_count())
        .map(|lane| {
            let end = world.road().lane_end(arena_sim::road::LaneId(lane as u32));
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
            _ => '>',
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
    text.push('\n');
    text
}

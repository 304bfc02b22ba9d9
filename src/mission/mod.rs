//! Missions, geofences and rally points as data: the items a client uploads
//! (MAVLink's MISSION_ITEM(_INT) fields, stored exactly as received), their
//! validation with PX4's MAV_MISSION_RESULT codes, PX4's CRC32 mission id,
//! and the files they come from (QGroundControl `.plan`, QGC WPL 110 text,
//! items in a scenario TOML) and persist to. Pure: no protocol, no clock.
//!
//! | file | job |
//! |---|---|
//! | `mod` | [`MissionItem`], [`MissionType`], [`MissionResult`], [`Plan`], item validation |
//! | `crc` | PX4's mission id: CRC32 over the items |
//! | `file` | `.plan`, WPL 110, the state-dir file (`missions.json`) |
//!
//! Coordinates: `x`, `y` hold MAVLink's param 5 and 6 in natural units —
//! degrees in the global frames (0, 3, 5, 6, 10, 11), the raw value in
//! MAV_FRAME_MISSION (2). An f64 holds both a MISSION_ITEM_INT's
//! `degE7 / 1e7` and a MISSION_ITEM's f32 exactly enough that either wire
//! form comes back bit for bit ([`MissionItem::x_int`], [`MissionItem::x_f32`]).

pub mod crc;
pub mod file;

use std::sync::Arc;

use serde::{Deserialize, Serialize};

use crate::geo::GeoPoint;

/// Most items a plan of any type may hold; a longer upload gets NO_SPACE.
pub const MAX_ITEMS: usize = 20_000;

/// MAV_MISSION_TYPE.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MissionType {
    /// 0: the mission.
    Mission,
    /// 1: geofence (polygon vertices and circles).
    Fence,
    /// 2: rally points.
    Rally,
}

impl MissionType {
    /// All three, in MAVLink order.
    pub const ALL: [MissionType; 3] = [MissionType::Mission, MissionType::Fence, MissionType::Rally];

    /// From MAV_MISSION_TYPE (255 ALL is not a single type: `None`).
    #[must_use]
    pub fn from_mav(v: u8) -> Option<Self> {
        match v {
            0 => Some(MissionType::Mission),
            1 => Some(MissionType::Fence),
            2 => Some(MissionType::Rally),
            _ => None,
        }
    }

    /// MAV_MISSION_TYPE value.
    #[must_use]
    pub fn to_mav(self) -> u8 {
        match self {
            MissionType::Mission => 0,
            MissionType::Fence => 1,
            MissionType::Rally => 2,
        }
    }

    /// Index 0..3 (for per-type arrays).
    #[must_use]
    pub fn index(self) -> usize {
        usize::from(self.to_mav())
    }

    /// Lower-case name for messages ("mission", "fence", "rally").
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            MissionType::Mission => "mission",
            MissionType::Fence => "fence",
            MissionType::Rally => "rally",
        }
    }
}

/// MAV_MISSION_RESULT, the answer in MISSION_ACK.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum MissionResult {
    /// 0
    Accepted,
    /// 1: generic error (also PX4's answer to a busy transfer).
    Error,
    /// 2: coordinate frame not supported.
    UnsupportedFrame,
    /// 3: command not supported.
    Unsupported,
    /// 4: more items than the vehicle stores.
    NoSpace,
    /// 5: one of the parameters has an invalid value.
    Invalid,
    /// 6
    InvalidParam1,
    /// 7
    InvalidParam2,
    /// 8
    InvalidParam3,
    /// 9
    InvalidParam4,
    /// 10: x / latitude.
    InvalidParam5X,
    /// 11: y / longitude.
    InvalidParam6Y,
    /// 12: z / altitude.
    InvalidParam7,
    /// 13: an item out of sequence.
    InvalidSequence,
    /// 14: not accepting now (another client's upload changed the plan).
    Denied,
    /// 15: the transfer was cancelled.
    OperationCancelled,
}

impl MissionResult {
    /// MAV_MISSION_RESULT value.
    #[must_use]
    pub fn to_mav(self) -> u8 {
        match self {
            MissionResult::Accepted => 0,
            MissionResult::Error => 1,
            MissionResult::UnsupportedFrame => 2,
            MissionResult::Unsupported => 3,
            MissionResult::NoSpace => 4,
            MissionResult::Invalid => 5,
            MissionResult::InvalidParam1 => 6,
            MissionResult::InvalidParam2 => 7,
            MissionResult::InvalidParam3 => 8,
            MissionResult::InvalidParam4 => 9,
            MissionResult::InvalidParam5X => 10,
            MissionResult::InvalidParam6Y => 11,
            MissionResult::InvalidParam7 => 12,
            MissionResult::InvalidSequence => 13,
            MissionResult::Denied => 14,
            MissionResult::OperationCancelled => 15,
        }
    }

    /// A short reason for a STATUSTEXT.
    #[must_use]
    pub fn reason(self) -> &'static str {
        match self {
            MissionResult::Accepted => "accepted",
            MissionResult::Error => "error",
            MissionResult::UnsupportedFrame => "unsupported frame",
            MissionResult::Unsupported => "unsupported command",
            MissionResult::NoSpace => "too many items",
            MissionResult::Invalid => "invalid item",
            MissionResult::InvalidParam1 => "invalid param 1",
            MissionResult::InvalidParam2 => "invalid param 2",
            MissionResult::InvalidParam3 => "invalid param 3",
            MissionResult::InvalidParam4 => "invalid param 4",
            MissionResult::InvalidParam5X => "invalid latitude / x",
            MissionResult::InvalidParam6Y => "invalid longitude / y",
            MissionResult::InvalidParam7 => "invalid altitude / z",
            MissionResult::InvalidSequence => "item out of sequence",
            MissionResult::Denied => "denied",
            MissionResult::OperationCancelled => "cancelled",
        }
    }
}

/// MAV_CMD numbers a mission may hold.
pub mod cmd {
    /// Fly to a point (p1 hold s, p2 acceptance m, p4 yaw deg).
    pub const NAV_WAYPOINT: u16 = 16;
    /// Loiter at a point until told otherwise.
    pub const NAV_LOITER_UNLIM: u16 = 17;
    /// Loiter p1 turns at a point.
    pub const NAV_LOITER_TURNS: u16 = 18;
    /// Loiter p1 seconds at a point.
    pub const NAV_LOITER_TIME: u16 = 19;
    /// Return to launch.
    pub const NAV_RETURN_TO_LAUNCH: u16 = 20;
    /// Land at a point (NaN lat/lon: here).
    pub const NAV_LAND: u16 = 21;
    /// Take off to the item's altitude.
    pub const NAV_TAKEOFF: u16 = 22;
    /// Loiter until an altitude is reached.
    pub const NAV_LOITER_TO_ALT: u16 = 31;
    /// Wait p1 seconds.
    pub const NAV_DELAY: u16 = 93;
    /// Jump to item p1, p2 times (-1 forever).
    pub const DO_JUMP: u16 = 177;
    /// Change the speed: p2 m/s.
    pub const DO_CHANGE_SPEED: u16 = 178;
    /// Set home: p1 = 1 here, else at the item's position.
    pub const DO_SET_HOME: u16 = 179;
    /// A servo (no-op here).
    pub const DO_SET_SERVO: u16 = 183;
    /// Land start marker.
    pub const DO_LAND_START: u16 = 189;
    /// Region of interest (no-op here).
    pub const DO_SET_ROI: u16 = 201;
    /// Gimbal (no-op here).
    pub const DO_MOUNT_CONTROL: u16 = 205;
    /// Camera trigger distance (no-op here).
    pub const DO_SET_CAM_TRIGG_DIST: u16 = 206;
    /// Camera trigger interval (no-op here).
    pub const DO_SET_CAM_TRIGG_INTERVAL: u16 = 214;
    /// Set the current mission item (as a command).
    pub const DO_SET_MISSION_CURRENT: u16 = 224;
    /// Camera mode, zoom, focus (no-op here).
    pub const SET_CAMERA_MODE: u16 = 530;
    /// Camera zoom (no-op here).
    pub const SET_CAMERA_ZOOM: u16 = 531;
    /// Camera focus (no-op here).
    pub const SET_CAMERA_FOCUS: u16 = 532;
    /// Gimbal manager pitch/yaw (no-op here).
    pub const DO_GIMBAL_MANAGER_PITCHYAW: u16 = 1000;
    /// Gimbal manager configure (no-op here).
    pub const DO_GIMBAL_MANAGER_CONFIGURE: u16 = 1001;
    /// Image capture start (no-op here).
    pub const IMAGE_START_CAPTURE: u16 = 2000;
    /// Image capture stop (no-op here).
    pub const IMAGE_STOP_CAPTURE: u16 = 2001;
    /// Video capture start (no-op here).
    pub const VIDEO_START_CAPTURE: u16 = 2500;
    /// Video capture stop (no-op here).
    pub const VIDEO_STOP_CAPTURE: u16 = 2501;
    /// VTOL transition (no-op for a multirotor).
    pub const DO_VTOL_TRANSITION: u16 = 3000;
    /// Fence polygon vertex, inclusion (p1 vertex count).
    pub const FENCE_POLYGON_VERTEX_INCLUSION: u16 = 5001;
    /// Fence polygon vertex, exclusion (p1 vertex count).
    pub const FENCE_POLYGON_VERTEX_EXCLUSION: u16 = 5002;
    /// Fence circle, inclusion (p1 radius m).
    pub const FENCE_CIRCLE_INCLUSION: u16 = 5003;
    /// Fence circle, exclusion (p1 radius m).
    pub const FENCE_CIRCLE_EXCLUSION: u16 = 5004;
    /// Fence return point.
    pub const FENCE_RETURN_POINT: u16 = 5000;
    /// Rally point.
    pub const RALLY_POINT: u16 = 5100;

    /// Commands a mission stores and completes at once (camera, gimbal,
    /// servo, VTOL, ROI, land start): PX4 accepts them, a simulator has
    /// nothing to do.
    pub const NO_OPS: [u16; 16] = [
        DO_SET_SERVO,
        DO_LAND_START,
        DO_SET_ROI,
        DO_MOUNT_CONTROL,
        DO_SET_CAM_TRIGG_DIST,
        DO_SET_CAM_TRIGG_INTERVAL,
        SET_CAMERA_MODE,
        SET_CAMERA_ZOOM,
        SET_CAMERA_FOCUS,
        DO_GIMBAL_MANAGER_PITCHYAW,
        DO_GIMBAL_MANAGER_CONFIGURE,
        IMAGE_START_CAPTURE,
        IMAGE_STOP_CAPTURE,
        VIDEO_START_CAPTURE,
        VIDEO_STOP_CAPTURE,
        DO_VTOL_TRANSITION,
    ];
}

/// MAV_FRAME numbers a plan may use, and how `x`, `y`, `z` read in each.
pub mod frame {
    /// 0: global, altitude AMSL.
    pub const GLOBAL: u8 = 0;
    /// 2: no position (params 5 to 7 are plain numbers).
    pub const MISSION: u8 = 2;
    /// 3: global, altitude relative to home.
    pub const GLOBAL_RELATIVE_ALT: u8 = 3;
    /// 5: the same as 0 (the `_INT` synonym).
    pub const GLOBAL_INT: u8 = 5;
    /// 6: the same as 3 (the `_INT` synonym; MAVSDK 3 sends it).
    pub const GLOBAL_RELATIVE_ALT_INT: u8 = 6;
    /// 10: global, altitude above terrain (flat ground here: above home).
    pub const GLOBAL_TERRAIN_ALT: u8 = 10;
    /// 11: the same as 10.
    pub const GLOBAL_TERRAIN_ALT_INT: u8 = 11;

    /// Whether `f` is one of the global frames (x, y are latitude, longitude in degrees).
    #[must_use]
    pub fn is_global(f: u8) -> bool {
        matches!(
            f,
            GLOBAL
                | GLOBAL_RELATIVE_ALT
                | GLOBAL_INT
                | GLOBAL_RELATIVE_ALT_INT
                | GLOBAL_TERRAIN_ALT
                | GLOBAL_TERRAIN_ALT_INT
        )
    }

    /// Whether the frame is one a plan accepts (PX4's, with the synonyms).
    #[must_use]
    pub fn is_supported(f: u8) -> bool {
        f == MISSION || is_global(f)
    }

    /// Whether `z` is an altitude above home (relative, or terrain on flat ground), not AMSL.
    #[must_use]
    pub fn is_relative(f: u8) -> bool {
        matches!(
            f,
            GLOBAL_RELATIVE_ALT | GLOBAL_RELATIVE_ALT_INT | GLOBAL_TERRAIN_ALT | GLOBAL_TERRAIN_ALT_INT
        )
    }
}

/// One stored item: MISSION_ITEM_INT's fields but the sequence number
/// (its index in the [`Plan`]) and the `current` flag (the vehicle's).
/// Equality is bit for bit (a NaN parameter equals the same NaN: stored
/// exactly as received).
#[derive(Clone, Copy, Debug, Serialize, Deserialize)]
pub struct MissionItem {
    /// MAV_FRAME as received (synonyms kept: 3 stays 3, 6 stays 6).
    pub frame: u8,
    /// MAV_CMD.
    pub command: u16,
    /// Continue to the next item when done.
    pub autocontinue: bool,
    /// param1 to param4 as received (NaN kept).
    pub params: [f32; 4],
    /// param5: latitude [deg] in global frames, else the raw value.
    pub x: f64,
    /// param6: longitude [deg] in global frames, else the raw value.
    pub y: f64,
    /// param7: altitude [m] (AMSL or relative, by the frame), else the raw value.
    pub z: f32,
}

impl PartialEq for MissionItem {
    fn eq(&self, o: &Self) -> bool {
        self.frame == o.frame
            && self.command == o.command
            && self.autocontinue == o.autocontinue
            && self.params.map(f32::to_bits) == o.params.map(f32::to_bits)
            && self.x.to_bits() == o.x.to_bits()
            && self.y.to_bits() == o.y.to_bits()
            && self.z.to_bits() == o.z.to_bits()
    }
}

impl Eq for MissionItem {}

impl MissionItem {
    /// The scale of `x`, `y` in MISSION_ITEM_INT: 1e7 in global frames, 1 otherwise.
    #[must_use]
    pub fn int_scale(frame: u8) -> f64 {
        if frame::is_global(frame) { 1e7 } else { 1.0 }
    }

    /// From MISSION_ITEM_INT's `x`, `y` (degE7 in global frames).
    #[must_use]
    pub fn xy_from_int(frame: u8, x: i32, y: i32) -> (f64, f64) {
        let s = Self::int_scale(frame);
        (f64::from(x) / s, f64::from(y) / s)
    }

    /// MISSION_ITEM_INT's `x` (rounded; NaN and overflow saturate as Rust's casts do).
    #[must_use]
    pub fn x_int(&self) -> i32 {
        (self.x * Self::int_scale(self.frame)).round() as i32
    }

    /// MISSION_ITEM_INT's `y`.
    #[must_use]
    pub fn y_int(&self) -> i32 {
        (self.y * Self::int_scale(self.frame)).round() as i32
    }

    /// MISSION_ITEM's `x` (float).
    #[must_use]
    pub fn x_f32(&self) -> f32 {
        self.x as f32
    }

    /// MISSION_ITEM's `y` (float).
    #[must_use]
    pub fn y_f32(&self) -> f32 {
        self.y as f32
    }

    /// The item's point — latitude, longitude and altitude AMSL, the relative
    /// frames above `home_alt_amsl_m` (terrain is flat: above home too) —
    /// or `None` when it has none (not positional, or NaN latitude/longitude: "here").
    #[must_use]
    pub fn geo_point(&self, home_alt_amsl_m: f64) -> Option<GeoPoint> {
        if !self.has_position() || self.x.is_nan() || self.y.is_nan() {
            return None;
        }
        Some(GeoPoint {
            lat_deg: self.x,
            lon_deg: self.y,
            alt_amsl_m: self.alt_amsl(home_alt_amsl_m),
        })
    }

    /// The altitude AMSL [m] of `z` in the item's frame (relative frames above `home_alt_amsl_m`).
    #[must_use]
    pub fn alt_amsl(&self, home_alt_amsl_m: f64) -> f64 {
        if frame::is_relative(self.frame) {
            home_alt_amsl_m + f64::from(self.z)
        } else {
            f64::from(self.z)
        }
    }

    /// Whether the command flies to or marks a position (x, y, z are a point).
    #[must_use]
    pub fn has_position(&self) -> bool {
        matches!(
            self.command,
            cmd::NAV_WAYPOINT
                | cmd::NAV_LOITER_UNLIM
                | cmd::NAV_LOITER_TURNS
                | cmd::NAV_LOITER_TIME
                | cmd::NAV_LAND
                | cmd::NAV_TAKEOFF
                | cmd::NAV_LOITER_TO_ALT
                | cmd::FENCE_POLYGON_VERTEX_INCLUSION
                | cmd::FENCE_POLYGON_VERTEX_EXCLUSION
                | cmd::FENCE_CIRCLE_INCLUSION
                | cmd::FENCE_CIRCLE_EXCLUSION
                | cmd::FENCE_RETURN_POINT
                | cmd::RALLY_POINT
        )
    }
}

/// `v` in degrees as MISSION_ITEM_INT carries it: `round(v * 1e7) / 1e7`.
/// A value that does not fit degE7 (beyond ±214.7°) or is not finite is kept
/// as it is: the check refuses it by its own value.
#[must_use]
pub fn quantise_deg(v: f64) -> f64 {
    let scaled = (v * 1e7).round();
    if scaled.is_finite() && scaled.abs() <= f64::from(i32::MAX) {
        MissionItem::xy_from_int(frame::GLOBAL, scaled as i32, 0).0
    } else {
        v
    }
}

/// Whether `item` may be stored in a plan of type `kind`: the command known
/// for that type, the frame supported, and every value the command needs a
/// number (PX4's MAV_MISSION_RESULT naming the first problem).
///
/// | check | answer |
/// |---|---|
/// | frame not 0, 2, 3, 5, 6, 10, 11 | UnsupportedFrame |
/// | command unknown, or of another plan type (a fence vertex in a mission) | Unsupported |
/// | a positional item in frame 2 | UnsupportedFrame |
/// | latitude not finite or beyond ±90° | InvalidParam5X |
/// | longitude not finite or beyond ±180° | InvalidParam6Y |
/// | altitude not finite | InvalidParam7 |
/// | a needed param NaN or out of range (hold time, radius, turns, delay, jump target and count, speed, vertex count) | InvalidParam1..4 |
///
/// NaN latitude and longitude together mean "here" for takeoff, land and
/// the loiters (PX4); a waypoint needs a position.
///
/// # Errors
/// The result that names the problem.
pub fn validate(kind: MissionType, item: &MissionItem) -> Result<(), MissionResult> {
    use MissionResult as R;
    let c = item.command;
    let known = match kind {
        MissionType::Mission => {
            matches!(
                c,
                cmd::NAV_WAYPOINT
                    | cmd::NAV_LOITER_UNLIM
                    | cmd::NAV_LOITER_TURNS
                    | cmd::NAV_LOITER_TIME
                    | cmd::NAV_RETURN_TO_LAUNCH
                    | cmd::NAV_LAND
                    | cmd::NAV_TAKEOFF
                    | cmd::NAV_LOITER_TO_ALT
                    | cmd::NAV_DELAY
                    | cmd::DO_JUMP
                    | cmd::DO_CHANGE_SPEED
                    | cmd::DO_SET_HOME
            ) || cmd::NO_OPS.contains(&c)
        }
        MissionType::Fence => matches!(
            c,
            cmd::FENCE_POLYGON_VERTEX_INCLUSION
                | cmd::FENCE_POLYGON_VERTEX_EXCLUSION
                | cmd::FENCE_CIRCLE_INCLUSION
                | cmd::FENCE_CIRCLE_EXCLUSION
                | cmd::FENCE_RETURN_POINT
        ),
        MissionType::Rally => c == cmd::RALLY_POINT,
    };
    if !frame::is_supported(item.frame) {
        return Err(R::UnsupportedFrame);
    }
    if !known {
        return Err(R::Unsupported);
    }
    let [p1, p2, _p3, _p4] = item.params.map(f64::from);
    let positional = item.has_position();
    let optional_position = matches!(
        c,
        cmd::NAV_TAKEOFF
            | cmd::NAV_LAND
            | cmd::NAV_LOITER_UNLIM
            | cmd::NAV_LOITER_TIME
            | cmd::NAV_LOITER_TURNS
            | cmd::NAV_LOITER_TO_ALT
    );
    if positional {
        if !frame::is_global(item.frame) {
            return Err(R::UnsupportedFrame);
        }
        let here = optional_position && item.x.is_nan() && item.y.is_nan();
        if !here {
            if !item.x.is_finite() || item.x.abs() > 90.0 {
                return Err(R::InvalidParam5X);
            }
            if !item.y.is_finite() || item.y.abs() > 180.0 {
                return Err(R::InvalidParam6Y);
            }
        }
        if !item.z.is_finite() {
            return Err(R::InvalidParam7);
        }
    }
    let nonneg_or_nan = |v: f64| v.is_nan() || v >= 0.0;
    match c {
        cmd::NAV_WAYPOINT if !nonneg_or_nan(p1) => Err(R::InvalidParam1),
        cmd::NAV_WAYPOINT if !(nonneg_or_nan(p2)) => Err(R::InvalidParam2),
        cmd::NAV_LOITER_TIME | cmd::NAV_DELAY if !(p1.is_finite() && p1 >= 0.0) => Err(R::InvalidParam1),
        cmd::NAV_LOITER_TURNS if !(p1.is_finite() && p1 >= 0.0) => Err(R::InvalidParam1),
        cmd::DO_JUMP if !(p1.is_finite() && p1 >= 0.0 && p1.fract() == 0.0) => Err(R::InvalidParam1),
        cmd::DO_JUMP if !(p2.is_finite() && p2 >= -1.0 && p2.fract() == 0.0) => Err(R::InvalidParam2),
        cmd::DO_CHANGE_SPEED if p2.is_nan() || p2.is_infinite() => Err(R::InvalidParam2),
        cmd::FENCE_POLYGON_VERTEX_INCLUSION | cmd::FENCE_POLYGON_VERTEX_EXCLUSION
            if !(p1.is_finite() && p1 >= 3.0 && p1.fract() == 0.0) =>
        {
            Err(R::InvalidParam1)
        }
        cmd::FENCE_CIRCLE_INCLUSION | cmd::FENCE_CIRCLE_EXCLUSION if !(p1.is_finite() && p1 >= 0.0) => {
            Err(R::InvalidParam1)
        }
        _ => Ok(()),
    }
}

/// A stored plan of one type: the items (shared, never changed in place:
/// a new upload is a new plan) and PX4's id of them ([`crc::plan_id`]).
#[derive(Clone, Debug, PartialEq, Default)]
pub struct Plan {
    items: Arc<[MissionItem]>,
    id: u32,
}

impl Plan {
    /// A plan of `kind` from `items`, each validated, with its id; or the
    /// first problem and the index of the item that has it.
    ///
    /// # Errors
    /// NoSpace beyond [`MAX_ITEMS`]; else the first item [`validate`] refuses.
    pub fn new(kind: MissionType, items: Vec<MissionItem>) -> Result<Self, (usize, MissionResult)> {
        if items.len() > MAX_ITEMS {
            return Err((MAX_ITEMS, MissionResult::NoSpace));
        }
        for (i, it) in items.iter().enumerate() {
            validate(kind, it).map_err(|r| (i, r))?;
        }
        let id = crc::plan_id(&items);
        Ok(Self {
            items: items.into(),
            id,
        })
    }

    /// The empty plan (id 0).
    #[must_use]
    pub fn empty() -> Self {
        Self::default()
    }

    /// The items, in sequence order.
    #[must_use]
    pub fn items(&self) -> &[MissionItem] {
        &self.items
    }

    /// Number of items.
    #[must_use]
    pub fn len(&self) -> usize {
        self.items.len()
    }

    /// No items.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.items.is_empty()
    }

    /// PX4's id of the plan (CRC32 of its items; 0 when empty).
    #[must_use]
    pub fn id(&self) -> u32 {
        self.id
    }
}

/// The three plans a vehicle stores.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct Plans {
    /// By [`MissionType::index`].
    pub by_type: [Plan; 3],
}

impl Plans {
    /// The plan of `kind`.
    #[must_use]
    pub fn get(&self, kind: MissionType) -> &Plan {
        &self.by_type[kind.index()]
    }

    /// Replace the plan of `kind`.
    pub fn set(&mut self, kind: MissionType, plan: Plan) {
        self.by_type[kind.index()] = plan;
    }
}

/// A change of the stored plans, as a client asks for it: applied whole or
/// not at all ([`Plans::apply`]).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum PlanChange {
    /// Replace the plan of `kind` with `items` — refused (Denied) if the
    /// stored plan's id is no longer `base_id`, the id it had when the
    /// upload began: another client changed it meanwhile.
    Store {
        /// Which plan.
        kind: MissionType,
        /// The complete upload, in sequence order.
        items: Vec<MissionItem>,
        /// The stored plan's id when the upload began (`None`: do not check).
        base_id: Option<u32>,
    },
    /// Clear one plan, or all three (`None`, MAV_MISSION_TYPE_ALL).
    Clear(Option<MissionType>),
}

impl Plans {
    /// Apply `change` whole or not at all: on success the new plan's id
    /// (0 for a clear).
    ///
    /// # Errors
    /// As [`Plan::new`] (the item index is dropped), or Denied when the
    /// stored plan changed since the upload began.
    pub fn apply(&mut self, change: PlanChange) -> Result<u32, MissionResult> {
        match change {
            PlanChange::Store { kind, items, base_id } => {
                if base_id.is_some_and(|b| b != self.get(kind).id()) {
                    return Err(MissionResult::Denied);
                }
                let plan = Plan::new(kind, items).map_err(|(_, r)| r)?;
                let id = plan.id();
                self.set(kind, plan);
                Ok(id)
            }
            PlanChange::Clear(kind) => {
                match kind {
                    Some(k) => self.set(k, Plan::empty()),
                    None => *self = Plans::default(),
                }
                Ok(0)
            }
        }
    }
}

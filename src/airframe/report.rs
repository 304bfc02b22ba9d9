//! What `rotorpilot airframe NAME` prints: allocation matrix, ranks, degrees
//! of freedom as the origin report counts them, underactuation, hover rotor
//! speeds and single-rotor-failure verdicts.
//!
//! Degrees of freedom (Grubler, `m = 6`): on the ground with spinning rotors
//! the body is fixed and each rotor adds one revolute joint, `DoF = n`
//! (configuration space `T^n`); flying adds the free body, `DoF = n + 6`
//! (`SE(3) x T^n`). A flat multirotor's body wrench map has rank 4 < 6: it
//! cannot produce horizontal force without tilting, hence underactuated.

use std::fmt::Write as _;

use serde::Serialize;

use super::{Actuation, Airframe, FailureAnalysis, HoverVerdict, TorqueMargins, rank, wrench_map};
use crate::signals::GRAVITY;

/// The full report, serialised as one JSON object by `--json`.
#[derive(Clone, Debug, Serialize)]
pub struct AirframeReport {
    /// Airframe name.
    pub name: String,
    /// Description.
    pub description: String,
    /// File or built-in label.
    pub source: String,
    /// How commands act.
    pub actuation: Actuation,
    /// Nominal mass [kg].
    pub mass_kg: f64,
    /// Rotor count.
    pub rotor_count: usize,
    /// `B` (4 x n), rows `[u_T, tau_x, tau_y, tau_z]`, SI units.
    pub allocation: Vec<Vec<f64>>,
    /// `rank B`.
    pub rank: usize,
    /// Rank of the 6 x n body wrench map.
    pub wrench_rank: usize,
    /// Degrees of freedom on the ground with spinning rotors.
    pub dof_ground: usize,
    /// Degrees of freedom flying.
    pub dof_flying: usize,
    /// Configuration space on the ground.
    pub configuration_space_ground: String,
    /// Configuration space flying.
    pub configuration_space_flying: String,
    /// Whether fewer independent inputs than the body's 6 DoF.
    pub underactuated: bool,
    /// Why.
    pub underactuated_reason: String,
    /// Hover thrust `m g` [N].
    pub hover_thrust_n: f64,
    /// Hover rotor speeds `sqrt(B^+ [m g, 0, 0, 0])` [rad/s].
    pub hover_rotor_speeds: Vec<f64>,
    /// Intact vehicle's hover verdict.
    pub hover: HoverVerdict,
    /// Intact vehicle's torque margins at hover.
    pub hover_margins: Option<TorqueMargins>,
    /// One entry per single-rotor failure.
    pub rotor_failure: Vec<FailureAnalysis>,
    /// Each rotor's motor number, from rotor 1: the number MAVLink clients
    /// give it ([`super::RotorGeometry::motor`], PX4's numbering).
    pub motors: Vec<usize>,
}

impl AirframeReport {
    /// Analyse an airframe.
    #[must_use]
    pub fn new(a: &Airframe) -> Self {
        let b = a.effectiveness();
        let n = a.rotor_count();
        let wrench_rank = rank(&wrench_map(&b));
        let hover_thrust_n = a.mass_kg * GRAVITY;
        let alloc = a.allocator();
        let hover_w = alloc.inverse(&crate::signals::ControlWrench::new(
            hover_thrust_n,
            nalgebra::Vector3::zeros(),
        ));
        let (hover, hover_margins) = super::intact_verdict(a);
        Self {
            name: a.name.clone(),
            description: a.description.clone(),
            source: a.source.clone(),
            actuation: a.actuation,
            mass_kg: a.mass_kg,
            rotor_count: n,
            allocation: b.row_iter().map(|r| r.iter().copied().collect()).collect(),
            rank: rank(&b),
            wrench_rank,
            dof_ground: n,
            dof_flying: n + 6,
            configuration_space_ground: format!("T^{n} (one angle per rotor; body fixed)"),
            configuration_space_flying: format!("SE(3) x T^{n}"),
            underactuated: wrench_rank < 6,
            underactuated_reason: format!(
                "all {n} rotors are coplanar and parallel: the 6-D body wrench map has rank {wrench_rank} < 6, \
                 so thrust acts only along -z_b and horizontal force needs a tilt"
            ),
            hover_thrust_n,
            hover_rotor_speeds: (0..n).map(|i| hover_w[i].max(0.0).sqrt()).collect(),
            hover,
            hover_margins,
            rotor_failure: super::analyse_failures(a),
            motors: a.rotors.iter().map(|r| r.motor).collect(),
        }
    }

    /// Human-readable rendering.
    #[must_use]
    pub fn to_text(&self) -> String {
        let mut s = String::new();
        let _ = writeln!(s, "airframe {} ({}) — {}", self.name, self.source, self.description);
        let _ = writeln!(
            s,
            "actuation: {}   mass: {} kg   rotors: {}",
            match self.actuation {
                Actuation::Rotors => "rotors (motor lag and limits)",
                Actuation::Ideal => "ideal (thrust and torque act directly)",
            },
            self.mass_kg,
            self.rotor_count
        );
        let motors: Vec<String> = self.motors.iter().map(ToString::to_string).collect();
        let _ = writeln!(
            s,
            "motor numbers of rotors 1 to {} (as MAVLink clients count them, PX4's): {}",
            self.rotor_count,
            motors.join(", ")
        );
        let _ = writeln!(
            s,
            "\nallocation matrix B ([u_T; tau_x; tau_y; tau_z] = B [w_1^2 .. w_n^2]):"
        );
        for (label, row) in ["u_T  ", "tau_x", "tau_y", "tau_z"].iter().zip(&self.allocation) {
            let cells: Vec<String> = row.iter().map(|v| format!("{v:>13.6e}")).collect();
            let _ = writeln!(s, "  {label} [{}]", cells.join(" "));
        }
        let _ = writeln!(
            s,
            "\nrank B = {}   rank of the 6-D wrench map = {}",
            self.rank, self.wrench_rank
        );
        let _ = writeln!(
            s,
            "degrees of freedom: {} on the ground with spinning rotors ({}), {} flying ({})",
            self.dof_ground, self.configuration_space_ground, self.dof_flying, self.configuration_space_flying
        );
        let _ = writeln!(
            s,
            "underactuated: {} — {}",
            if self.underactuated { "yes" } else { "no" },
            self.underactuated_reason
        );
        let speeds: Vec<String> = self.hover_rotor_speeds.iter().map(|w| format!("{w:.3}")).collect();
        let _ = writeln!(
            s,
            "\nhover: thrust {:.4} N, rotor speeds [{}] rad/s",
            self.hover_thrust_n,
            speeds.join(", ")
        );
        if let Some(m) = &self.hover_margins {
            let _ = writeln!(s, "  torque margins at hover: {}", margins_text(m));
        }
        let _ = writeln!(s, "\nsingle rotor failure:");
        for f in &self.rotor_failure {
            let what = match f.verdict {
                HoverVerdict::Feasible => "hover feasible, full attitude control".to_string(),
                HoverVerdict::Boundary => {
                    "hover only on the boundary: some torque direction has no margin (yaw or roll/pitch cannot be held)"
                        .to_string()
                }
                HoverVerdict::RankDeficient => {
                    "rank deficient: give up yaw and control the thrust direction only".to_string()
                }
                HoverVerdict::Infeasible => "hover infeasible within the rotor speed limits".to_string(),
            };
            let motor = self.motors.get(f.rotor.wrapping_sub(1)).copied().unwrap_or(f.rotor);
            let _ = write!(s, "  rotor {:>2} (motor {motor}): rank {}, {what}", f.rotor, f.rank);
            if let Some(m) = &f.margins {
                let _ = write!(s, "; margins {}", margins_text(m));
            }
            s.push('\n');
        }
        s
    }
}

fn margins_text(m: &TorqueMargins) -> String {
    format!(
        "roll -{:.3}/+{:.3}, pitch -{:.3}/+{:.3}, yaw -{:.3}/+{:.3} N m",
        m.roll_n_m[0], m.roll_n_m[1], m.pitch_n_m[0], m.pitch_n_m[1], m.yaw_n_m[0], m.yaw_n_m[1]
    )
}

//! Rotor failure detection from ESC telemetry: what each motor was commanded
//! against the speed its ESC reports (`docs/model.md` section 3b).
//!
//! A healthy motor follows its command through the first-order lag
//! `omega' = (c - omega) / tau_m`, `c = clamp(omega_cmd, omega_min, omega_max)`
//! held over each step, so the monitor predicts its speed with the exact
//! discrete lag
//!
//! `omega_hat_k = c_{k-1} + (omega_hat_{k-1} - c_{k-1}) e^{-(t_k - t_{k-1}) / tau_m}`
//!
//! (open loop from the first reading: a stable lag forgets its start, so a
//! model error only gives a decaying transient, never a drift). Comparing the
//! measurement with this prediction, not with the raw command, makes speed
//! steps and saturation of a healthy motor invisible. The residual is the
//! speed ratio `rho = omega_meas / omega_hat`:
//!
//! * `rho >= 0.95` (thrust `>= 90 %`): nominal;
//! * `rho <` [`FAILED_SPEED_RATIO`] (thrust below 9 %): failed (a dead motor
//!   spins down, `rho ~ e^{-t/tau_m}`);
//! * otherwise degraded with thrust fraction `f = rho^2` (a motor reaching
//!   `sqrt(f)` of its command has `rho(t) = sqrt(f) + (1 - sqrt(f)) e^{-t/tau_m}`
//!   after the fault, within 2 % of `sqrt(f)` after `4 tau_m`).
//!
//! A verdict changes only after the evidence against it has held without a
//! break for the confirmation time ([`RotorMonitor::confirm_s`], `3 tau_m`
//! plus one `tau_m` of margin: 80 ms for a 20 ms motor), and the new verdict is
//! read from the ratio at that instant. A dead rotor is therefore flagged
//! about `4.05 tau_m` after it loses power; a flagged rotor that follows its
//! command again (`rho >= 0.97` for the same time) is taken back. Readings
//! with a predicted speed below half the idle speed (rotors stopped) carry no
//! evidence.

use crate::signals::{ActuatorCommand, MAX_ROTORS, RotorVector};

/// Below this speed ratio `omega_meas / omega_hat` a rotor counts as failed
/// (thrust fraction below `0.3^2 = 9 %`).
pub const FAILED_SPEED_RATIO: f64 = 0.3;
/// Below this ratio a healthy rotor is suspect (thrust fraction below ~90 %).
const SUSPECT_SPEED_RATIO: f64 = 0.95;
/// At or above this ratio a flagged rotor follows its command again.
const RECOVERED_SPEED_RATIO: f64 = 0.97;
/// A degraded rotor is re-estimated when its thrust fraction moves by more than this.
const FRACTION_CHANGE: f64 = 0.1;
/// The confirmation time in motor time constants (`3 tau_m` plus a margin of one).
const CONFIRM_TAU: f64 = 4.0;

/// The monitor's verdict on one rotor.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum RotorStatus {
    /// Follows its command.
    Healthy,
    /// Reaches only part of its commanded speed: `thrust_fraction = rho^2` in `[0.09, 0.9)`.
    Degraded {
        /// Estimated thrust fraction `T / T_cmd`.
        thrust_fraction: f64,
    },
    /// Does not spin up: removed from the allocation.
    Failed,
}

impl RotorStatus {
    /// The verdict a speed ratio `rho` reads as.
    fn from_ratio(rho: f64) -> Self {
        if rho >= RECOVERED_SPEED_RATIO {
            RotorStatus::Healthy
        } else if rho < FAILED_SPEED_RATIO {
            RotorStatus::Failed
        } else {
            RotorStatus::Degraded {
                thrust_fraction: rho * rho,
            }
        }
    }

    /// Whether ratio `rho` contradicts this verdict.
    fn contradicted_by(self, rho: f64) -> bool {
        match self {
            RotorStatus::Healthy => rho < SUSPECT_SPEED_RATIO,
            RotorStatus::Failed => rho >= FAILED_SPEED_RATIO,
            RotorStatus::Degraded { thrust_fraction } => {
                !(FAILED_SPEED_RATIO..RECOVERED_SPEED_RATIO).contains(&rho)
                    || (rho * rho - thrust_fraction).abs() > FRACTION_CHANGE
            }
        }
    }

    /// The thrust the allocation may count on from this rotor, as a fraction of nominal.
    #[must_use]
    pub fn thrust_fraction(self) -> f64 {
        match self {
            RotorStatus::Healthy => 1.0,
            RotorStatus::Degraded { thrust_fraction } => thrust_fraction,
            RotorStatus::Failed => 0.0,
        }
    }
}

/// A verdict that changed at one step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RotorEvent {
    /// Rotor index, from 0 (rotor label `index + 1`).
    pub index: usize,
    /// The verdict before.
    pub from: RotorStatus,
    /// The verdict now.
    pub to: RotorStatus,
    /// When the evidence started [s] (the first contradicting reading).
    pub evidence_since_s: f64,
}

/// Commanded-versus-measured rotor speed supervision of one vehicle (module doc).
#[derive(Clone, Debug)]
pub struct RotorMonitor {
    n: usize,
    tau_s: f64,
    speed_min: f64,
    speed_max: f64,
    confirm_s: f64,
    /// `omega_hat` at `last_time_s` [rad/s].
    predicted: RotorVector,
    /// What the motors are driven towards since `last_time_s`: `clamp(omega_cmd)`, 0 when stopped.
    target: RotorVector,
    last_time_s: Option<f64>,
    status: [RotorStatus; MAX_ROTORS],
    /// The first reading of an unbroken run contradicting the verdict [s].
    since_s: [Option<f64>; MAX_ROTORS],
    /// The last interval between readings (its bits) and its decay
    /// `e^{-h/tau_m}`: readings come at a fixed step, so `exp` runs once per
    /// change of the interval, not once per reading.
    last_decay: Option<(u64, f64)>,
}

impl RotorMonitor {
    /// A monitor for `n` rotors with motor time constant `tau_s` [s] and
    /// speed limits [rad/s]; every rotor healthy.
    #[must_use]
    pub fn new(n: usize, tau_s: f64, speed_min: f64, speed_max: f64) -> Self {
        Self {
            n: n.min(MAX_ROTORS),
            tau_s,
            speed_min,
            speed_max,
            confirm_s: CONFIRM_TAU * tau_s,
            predicted: RotorVector::zeros(),
            target: RotorVector::zeros(),
            last_time_s: None,
            status: [RotorStatus::Healthy; MAX_ROTORS],
            last_decay: None,
            since_s: [None; MAX_ROTORS],
        }
    }

    /// How long evidence must hold before a verdict changes [s] (`4 tau_m`).
    #[must_use]
    pub fn confirm_s(&self) -> f64 {
        self.confirm_s
    }

    /// The verdict per rotor (the first [`Self::rotor_count`] entries).
    #[must_use]
    pub fn status(&self) -> &[RotorStatus] {
        &self.status[..self.n]
    }

    /// Number of rotors supervised.
    #[must_use]
    pub fn rotor_count(&self) -> usize {
        self.n
    }

    /// Rotors not healthy, as 1-based labels.
    #[must_use]
    pub fn flagged(&self) -> Vec<usize> {
        (0..self.n)
            .filter(|i| self.status[*i] != RotorStatus::Healthy)
            .map(|i| i + 1)
            .collect()
    }

    /// The predicted speeds `omega_hat` at the latest reading [rad/s].
    #[must_use]
    pub fn predicted(&self) -> &RotorVector {
        &self.predicted
    }

    /// Forget the prediction: the next reading starts it again (after the
    /// world overrode the command, e.g. stopped the rotors). Verdicts stay.
    pub fn resync(&mut self) {
        self.last_time_s = None;
        self.since_s = [None; MAX_ROTORS];
    }

    /// The command the motors get from now until the next reading.
    pub fn commanded(&mut self, command: &ActuatorCommand) {
        self.target = match command {
            ActuatorCommand::RotorSpeeds(w) => w.map(|x| x.clamp(self.speed_min, self.speed_max)),
            ActuatorCommand::Stop | ActuatorCommand::Wrench(_) => RotorVector::zeros(),
        };
    }

    /// The ESCs of `rotors` (indices from 0) report healthy again while the
    /// rotors are stopped (PX4's failure injector cleared, FAILURE_TYPE_OK):
    /// with no speed to judge, their verdicts go back to healthy, as PX4's
    /// failure detector forgets a motor failure once disarmed. Returns the
    /// verdicts that changed (stamped `time_s`).
    pub fn reported_healthy(&mut self, rotors: &[usize], time_s: f64) -> Vec<RotorEvent> {
        let mut events = Vec::new();
        for &i in rotors.iter().filter(|&&i| i < self.n) {
            let from = self.status[i];
            self.since_s[i] = None;
            if from != RotorStatus::Healthy {
                self.status[i] = RotorStatus::Healthy;
                events.push(RotorEvent {
                    index: i,
                    from,
                    to: RotorStatus::Healthy,
                    evidence_since_s: time_s,
                });
            }
        }
        events
    }

    /// The ESC readings `measured` [rad/s] at `time_s`: advance the
    /// prediction over the held command, compare, and return the verdicts that changed.
    pub fn update(&mut self, time_s: f64, measured: &RotorVector) -> Vec<RotorEvent> {
        let Some(last) = self.last_time_s else {
            self.predicted = *measured;
            self.last_time_s = Some(time_s);
            return Vec::new();
        };
        let h = time_s - last;
        if h.is_nan() || h <= 0.0 {
            return Vec::new();
        }
        self.last_time_s = Some(time_s);
        let decay = match self.last_decay {
            Some((bits, decay)) if bits == h.to_bits() => decay,
            _ => {
                let decay = (-h / self.tau_s).exp();
                self.last_decay = Some((h.to_bits(), decay));
                decay
            }
        };
        let mut events = Vec::new();
        for i in 0..self.n {
            let c = self.target[i];
            self.predicted[i] = c + (self.predicted[i] - c) * decay;
            let p = self.predicted[i];
            let m = measured[i];
            if p.is_nan() || p < 0.5 * self.speed_min || !m.is_finite() {
                // stopped: no evidence either way
                self.since_s[i] = None;
                continue;
            }
            let rho = m / p;
            let status = self.status[i];
            if !status.contradicted_by(rho) {
                self.since_s[i] = None;
                continue;
            }
            let since = *self.since_s[i].get_or_insert(time_s);
            if time_s - since >= self.confirm_s - 1e-9 {
                let to = RotorStatus::from_ratio(rho);
                self.since_s[i] = None;
                if to != status {
                    self.status[i] = to;
                    events.push(RotorEvent {
                        index: i,
                        from: status,
                        to,
                        evidence_since_s: since,
                    });
                }
            }
        }
        events
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const DT: f64 = 1e-3;
    const TAU: f64 = 0.02;

    /// A first-order motor (the plant's exact lag) with a speed factor.
    fn motor_step(omega: f64, cmd: f64, factor: f64) -> f64 {
        let c = factor * cmd.clamp(100.0, 1000.0);
        c + (omega - c) * (-DT / TAU).exp()
    }

    /// Run 4 rotors for `steps`; rotor 0 gets `factor(t)` and the command `cmd(t)`.
    fn run(
        steps: usize,
        cmd: impl Fn(f64) -> f64,
        factor: impl Fn(f64) -> f64,
    ) -> (RotorMonitor, Vec<(f64, RotorEvent)>) {
        let mut mon = RotorMonitor::new(4, TAU, 100.0, 1000.0);
        let mut omega = RotorVector::zeros();
        omega.rows_mut(0, 4).fill(400.0);
        let mut events = Vec::new();
        for k in 0..steps {
            let t = k as f64 * DT;
            for e in mon.update(t, &omega) {
                events.push((t, e));
            }
            let mut w = RotorVector::zeros();
            w.rows_mut(0, 4).fill(cmd(t));
            mon.commanded(&ActuatorCommand::RotorSpeeds(w));
            for i in 0..4 {
                omega[i] = motor_step(omega[i], w[i], if i == 0 { factor(t) } else { 1.0 });
            }
        }
        (mon, events)
    }

    #[test]
    fn steps_and_saturation_of_healthy_motors_never_trip() {
        // bang-bang between idle and beyond the top speed every 10 ms
        let (mon, events) = run(
            3000,
            |t| if (t * 100.0) as i64 % 2 == 0 { 50.0 } else { 2000.0 },
            |_| 1.0,
        );
        assert!(events.is_empty(), "{events:?}");
        assert!(mon.flagged().is_empty());
    }

    #[test]
    fn a_dead_motor_is_flagged_after_about_four_time_constants() {
        let (mon, events) = run(1000, |_| 400.0, |t| if t >= 0.5 { 0.0 } else { 1.0 });
        assert_eq!(events.len(), 1, "{events:?}");
        let (t, e) = events[0];
        assert_eq!((e.index, e.to), (0, RotorStatus::Failed));
        let delay = t - 0.5;
        assert!(delay > 0.08 && delay < 0.09, "flagged {delay} s after the fault");
        assert_eq!(mon.flagged(), vec![1]);
    }

    #[test]
    fn a_half_thrust_motor_is_degraded_with_its_fraction_and_taken_back_when_repaired() {
        let (mon, events) = run(
            2000,
            |_| 400.0,
            |t| if (0.5..1.2).contains(&t) { 0.5f64.sqrt() } else { 1.0 },
        );
        assert_eq!(events.len(), 2, "{events:?}");
        let RotorStatus::Degraded { thrust_fraction } = events[0].1.to else {
            panic!("{events:?}")
        };
        assert!((thrust_fraction - 0.5).abs() < 0.02, "fraction {thrust_fraction}");
        assert!(events[0].0 - 0.5 < 0.1);
        assert_eq!(events[1].1.to, RotorStatus::Healthy);
        assert!(events[1].0 > 1.2 && events[1].0 - 1.2 < 0.1);
        assert!(mon.flagged().is_empty());
    }

    #[test]
    fn a_stopped_vehicle_gives_no_evidence() {
        let mut mon = RotorMonitor::new(4, TAU, 100.0, 1000.0);
        for k in 0..500 {
            assert!(mon.update(k as f64 * DT, &RotorVector::zeros()).is_empty());
            mon.commanded(&ActuatorCommand::Stop);
        }
        assert!(mon.flagged().is_empty());
    }
}

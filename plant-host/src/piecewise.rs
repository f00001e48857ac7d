//! The integrator: the plant is linear inside each contact mode (gap open, driving contact,
//! braking contact), so each mode is stepped EXACTLY by its zero-order-hold discretisation
//! ([`crate::discrete`], cached per step length). After every step the mode's guards (the
//! dead-zone edges, or the clamp's force sign) are checked at the end points, with a tangent
//! bound for a crossing hidden between them; when a guard may have fired, the step is redone
//! from its start with the mode's Taylor series (exact to ~1e-16 for ‖A‖·h ≤ 0.5), the
//! crossing time is found ([`crate::events`]), the mode switches there and the rest of the
//! step continues in the new mode. Errors are set by round-off and the root tolerance
//! (1e-15 s), not by a step size.
//!
//! A step length not seen before costs one 8×8 matrix exponential per mode (a few µs);
//! callers that repeat the same few lengths (a harness's delay and remainder) hit the cache.

use crate::config::BacklashModel;
use crate::discrete::MapCache;
use crate::events::{Guards, Taylor};
use crate::model::{Contact, Model, Shaft, Vec3, Vec5, row_sum_norm};

/// Mode changes allowed inside one step before the rest is stepped without guards
/// (protects against chattering at a grazing contact).
const MAX_EVENTS_PER_STEP: u32 = 32;

/// A step length as [`Piecewise::advance`] splits it: `pieces` sub-steps of `h`, whose maps
/// sit in the cache's `slot`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Split {
    h: f64,
    pieces: u64,
    slot: usize,
}

/// The piecewise-linear two-inertia plant (optionally with its winding).
#[derive(Debug, Clone)]
pub(crate) struct Piecewise {
    maps: MapCache,
    guards: [Guards; 3],
    shaft: Shaft,
    law: BacklashModel,
    h_max_s: f64,
    /// Mode changes allowed inside one step ([`MAX_EVENTS_PER_STEP`]).
    max_events: u32,
    x: Vec5,
    contact: Contact,
    events: u64,
    searches: u64,
}

impl Piecewise {
    pub fn new(model: &Model) -> Self {
        let systems = Contact::ALL.map(|c| model.matrices(c));
        let norm = systems
            .iter()
            .map(|(a, _)| row_sum_norm(a))
            .fold(0.0, f64::max);
        // ‖A‖·h ≤ 0.5 keeps the Taylor series short and the tangent bound tight; 250 µs keeps
        // the crossing search (16 samples per step) fine even for slow plants.
        // Configs from TOML are checked to ‖A‖ ≤ 1e6 1/s; a hand-built absurd one is still
        // stepped (exactly between edges) with sub-steps no shorter than 0.5 µs, never hung.
        let h_max_s = (0.5 / norm.clamp(1e-9, 1e6)).min(250e-6);
        let guards = Contact::ALL.map(|c| {
            let (a, b) = model.matrices(c);
            Guards::new(c, model.law, &model.shaft, &a, &b)
        });
        let mut p = Self {
            maps: MapCache::new(systems),
            guards,
            shaft: model.shaft,
            law: model.law,
            h_max_s,
            max_events: MAX_EVENTS_PER_STEP,
            x: Vec5::zeros(),
            contact: Contact::Free,
            events: 0,
            searches: 0,
        };
        p.contact = p.contact_for(&p.x);
        p
    }

    /// The longest internal step, s.
    pub fn max_step_s(&self) -> f64 {
        self.h_max_s
    }

    pub fn state(&self) -> &Vec5 {
        &self.x
    }

    // The state vector is (x, y, z, w, a) = (twist δ rad, load angle θl rad, motor speed
    // ωm pu, load speed ωl pu, winding current pu); these name its parts once for both
    // plants.

    /// Motor angle θm = θl + δ, rad.
    pub fn motor_pos_rad(&self) -> f64 {
        self.x.y + self.x.x
    }

    /// Load angle θl (motor side), rad.
    pub fn load_pos_rad(&self) -> f64 {
        self.x.y
    }

    /// Motor speed ωm, pu.
    pub fn motor_vel_pu(&self) -> f64 {
        self.x.z
    }

    /// Load speed ωl (motor side), pu.
    pub fn load_vel_pu(&self) -> f64 {
        self.x.w
    }

    /// Twist δ = θm − θl, rad.
    pub fn twist_rad(&self) -> f64 {
        self.x.x
    }

    pub fn contact(&self) -> Contact {
        self.contact
    }

    pub fn mode_changes(&self) -> u64 {
        self.events
    }

    /// Steps redone with the Taylor series to search for a crossing (cost diagnostics).
    pub fn crossing_searches(&self) -> u64 {
        self.searches
    }

    /// Sets the state; the contact mode follows from the twist (and, clamped, the force sign).
    pub fn set_state(&mut self, x: Vec5) {
        self.x = x;
        self.contact = self.contact_for(&x);
    }

    fn contact_for(&self, x: &Vec5) -> Contact {
        let Shaft { k, d, g } = self.shaft;
        let (delta, rel) = (x.x, x.z - x.w);
        let dz_law = if g == 0.0 && self.law == BacklashModel::DeadZone {
            // No lost motion: one linear mode, never switching.
            return Contact::Driving;
        } else if delta > g {
            Contact::Driving
        } else if delta < -g {
            Contact::Braking
        } else {
            Contact::Free
        };
        match (self.law, dz_law) {
            (BacklashModel::Clamped, Contact::Driving) if k * (delta - g) + d * rel <= 0.0 => {
                Contact::Free
            }
            (BacklashModel::Clamped, Contact::Braking) if k * (delta + g) + d * rel >= 0.0 => {
                Contact::Free
            }
            _ => dz_law,
        }
    }

    /// Shaft torque Ts in pu for the current state and mode.
    pub fn shaft_torque_pu(&self) -> f64 {
        let Shaft { k, d, g } = self.shaft;
        let (delta, rel) = (self.x.x, self.x.z - self.x.w);
        match self.contact {
            Contact::Free => 0.0,
            Contact::Driving => k * (delta - g) + d * rel,
            Contact::Braking => k * (delta + g) + d * rel,
        }
    }

    /// Advances by `dt_s` with the inputs held. `dt_s` must be finite and ≥ 0 (checked by callers).
    pub fn advance(&mut self, dt_s: f64, u: &Vec3) {
        let (pieces, h) = self.pieces(dt_s);
        if pieces == 1 {
            // The usual case (a harness step is shorter than the longest sub-step).
            self.piece(h, u);
            return;
        }
        for _ in 0..pieces {
            self.piece(h, u);
        }
    }

    /// How a step of `dt_s` is split: `pieces` sub-steps of `h`, none of them longer than
    /// the longest sub-step (no pieces for a step that is not positive).
    #[inline(always)]
    fn pieces(&self, dt_s: f64) -> (u64, f64) {
        if dt_s <= 0.0 {
            (0, 0.0)
        } else if dt_s <= self.h_max_s {
            (1, dt_s)
        } else {
            let pieces = (dt_s / self.h_max_s).ceil().max(1.0);
            (pieces as u64, dt_s / pieces)
        }
    }

    /// How [`Self::advance`] splits a step of `dt_s`, with the slot of its sub-step's
    /// maps, worked out once for a caller that repeats the step.
    pub fn split(&mut self, dt_s: f64) -> Split {
        let (pieces, h) = self.pieces(dt_s);
        let slot = if pieces > 0 { self.maps.slot(h) } else { 0 };
        Split { h, pieces, slot }
    }

    /// [`Self::advance`] by a step split by [`Self::split`]: the same sub-steps, each map
    /// taken from its slot without a scan.
    #[inline(always)]
    pub fn advance_split(&mut self, split: &Split, u: &Vec3) {
        let Split { h, pieces, slot } = *split;
        if pieces == 1 {
            self.piece_in(slot, h, u);
            return;
        }
        for _ in 0..pieces {
            self.piece_in(slot, h, u);
        }
    }

    fn guards(&self) -> &Guards {
        let [free, driving, braking] = &self.guards;
        match self.contact {
            Contact::Free => free,
            Contact::Driving => driving,
            Contact::Braking => braking,
        }
    }

    /// One sub-step: the cached exact map and the cheap guard test; the event search only
    /// when a guard may have fired.
    #[inline]
    fn piece(&mut self, h: f64, u: &Vec3) {
        let x_end = self.maps.step(self.contact, h, &self.x, u);
        self.settle(x_end, h, u);
    }

    /// [`Self::piece`] with the map's slot known.
    #[inline(always)]
    fn piece_in(&mut self, slot: usize, h: f64, u: &Vec3) {
        let x_end = self.maps.step_in(slot, self.contact, h, &self.x, u);
        self.settle(x_end, h, u);
    }

    /// The end of a sub-step whose exact map gave `x_end`: taken as it is unless a guard
    /// may have fired, then the event search.
    #[inline(always)]
    fn settle(&mut self, x_end: Vec5, h: f64, u: &Vec3) {
        if self.guards().suspect(&self.x, &x_end, u, h) {
            self.search(self.x, x_end, h, u);
        } else {
            self.x = x_end;
        }
    }

    /// Redoes a suspect step with the Taylor series: finds the earliest crossing, switches
    /// mode there, and continues (Taylor again) for the rest of the step.
    #[cold]
    fn search(&mut self, mut x0: Vec5, mut x_end: Vec5, h: f64, u: &Vec3) {
        let mut remaining = h;
        let mut changes = 0;
        loop {
            let (a, b) = self.maps.system(self.contact);
            let taylor = Taylor::new(a, b, &x0, u, remaining);
            self.searches += 1;
            let Some((tau, target)) = self.guards().first_crossing(&taylor, remaining) else {
                self.x = x_end;
                return;
            };
            self.x = taylor.state(tau);
            self.contact = target;
            self.events += 1;
            changes += 1;
            remaining -= tau;
            if remaining <= 0.0 {
                return;
            }
            x0 = self.x;
            let (a, b) = self.maps.system(self.contact);
            x_end = Taylor::new(a, b, &x0, u, remaining).state(remaining);
            if changes >= self.max_events || !self.guards().suspect(&x0, &x_end, u, remaining) {
                self.x = x_end;
                return;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
    use super::*;
    use crate::model::test_model;

    /// A step is cut into the fewest equal sub-steps no longer than the longest one; a step
    /// that is not positive has none.
    #[test]
    fn a_step_is_cut_into_the_fewest_equal_pieces_within_the_longest_sub_step() {
        let p = Piecewise::new(&test_model(BacklashModel::DeadZone));
        let h = p.max_step_s();
        assert!(h > 0.0 && h <= 250e-6, "{h}");
        assert_eq!(p.pieces(0.5 * h), (1, 0.5 * h));
        assert_eq!(p.pieces(h), (1, h));
        assert_eq!(p.pieces(3.5 * h), (4, 3.5 * h / 4.0));
        assert_eq!(p.pieces(0.0), (0, 0.0));
        assert_eq!(p.pieces(-h), (0, 0.0));
    }

    /// The contact set with a state: beyond an edge the gears engage (the dead zone), and
    /// under the clamped law only while the contact force pushes them together,
    /// K·(δ ∓ g) + D·(ωm − ωl) of the edge's sign; inside the gap, and exactly on an edge,
    /// they are apart. On a grid of twists and relative speeds around both edges.
    #[test]
    fn the_contact_follows_the_twist_and_under_the_clamp_the_force() {
        for law in [BacklashModel::DeadZone, BacklashModel::Clamped] {
            let m = test_model(law);
            let Shaft { k, d, g } = m.shaft;
            let mut p = Piecewise::new(&m);
            let mut seen = [0; 3];
            for i in -12..=12 {
                let delta = g * f64::from(i) / 4.0;
                for j in -8..=8 {
                    let rel = 0.1 * f64::from(j);
                    let x = Vec5::new(delta, 0.7, 0.3 + rel, 0.3, 0.1);
                    p.set_state(x);
                    assert_eq!(p.twist_rad(), delta);
                    assert_eq!(*p.state(), x);
                    let rel = x.z - x.w;
                    let force_driving = k * (delta - g) + d * rel;
                    let force_braking = k * (delta + g) + d * rel;
                    let clamped = law == BacklashModel::Clamped;
                    let want = if delta > g && !(clamped && force_driving <= 0.0) {
                        Contact::Driving
                    } else if delta < -g && !(clamped && force_braking >= 0.0) {
                        Contact::Braking
                    } else {
                        Contact::Free
                    };
                    assert_eq!(p.contact(), want, "{law:?} δ = {delta}, ωm − ωl = {rel}");
                    seen[want.index()] += 1;
                }
            }
            // Every mode is met, and the clamp releases some states beyond each edge.
            assert!(seen.iter().all(|&n| n > 0), "{law:?} {seen:?}");
        }
    }

    /// Without lost motion (g = 0) the dead zone is one linear mode that never switches,
    /// while the clamp still releases when the contact force turns to pull: through a
    /// shaft oscillation that reverses the twist, the dead zone stays engaged with no mode
    /// change and the clamped law changes mode.
    #[test]
    fn without_lost_motion_only_the_clamp_changes_mode() {
        for law in [BacklashModel::DeadZone, BacklashModel::Clamped] {
            let mut m = test_model(law);
            m.shaft.g = 0.0;
            let mut p = Piecewise::new(&m);
            p.set_state(Vec5::new(0.001, 0.0, 0.1, 0.0, 0.0));
            assert_eq!(p.contact(), Contact::Driving, "{law:?}");
            let mut reversed = false;
            for _ in 0..200 {
                p.advance(250e-6, &Vec3::new(0.1, 0.0, 1.0));
                reversed |= p.twist_rad() < -1e-4;
            }
            assert!(reversed, "{law:?}: the twist never reversed");
            match law {
                BacklashModel::DeadZone => {
                    assert_eq!((p.mode_changes(), p.contact()), (0, Contact::Driving));
                }
                BacklashModel::Clamped => assert!(p.mode_changes() > 0),
            }
        }
    }

    /// Two mode changes in one sub-step: from just inside the driving contact, the motor
    /// 0.5 pu slower than the load, the gears part at once and the twist crosses the whole
    /// 8 mrad gap to the braking edge in about 53 µs. Each change takes one search, and the
    /// step ends in braking contact; with the cap on changes set to one, it stops after the
    /// first (the rest of the step in the free mode).
    #[test]
    fn a_sub_step_takes_every_mode_change_in_it_up_to_the_cap() {
        let m = test_model(BacklashModel::DeadZone);
        let u = Vec3::new(0.0, 0.0, 1.0);
        let start = Vec5::new(m.shaft.g + 1e-7, 0.0, 0.0, 0.5, 0.0);
        let mut p = Piecewise::new(&m);
        assert!(p.max_step_s() > 60e-6, "{}", p.max_step_s());
        p.set_state(start);
        assert_eq!(p.contact(), Contact::Driving);
        p.advance(60e-6, &u);
        assert_eq!(p.contact(), Contact::Braking);
        assert_eq!((p.mode_changes(), p.crossing_searches()), (2, 2));
        let mut capped = Piecewise::new(&m);
        capped.max_events = 1;
        capped.set_state(start);
        capped.advance(60e-6, &u);
        assert_eq!(capped.contact(), Contact::Free);
        assert_eq!((capped.mode_changes(), capped.crossing_searches()), (1, 1));
        assert!(capped.twist_rad() < -m.shaft.g, "{}", capped.twist_rad());
    }

    /// The cost counter: no search while the gears stay apart in the middle of the gap; a
    /// search for each suspect step of a run that crosses an edge, at least one per mode
    /// change.
    #[test]
    fn crossing_searches_count_the_redone_steps() {
        let m = test_model(BacklashModel::DeadZone);
        let u = Vec3::new(0.0, 0.0, 1.0);
        let mut p = Piecewise::new(&m);
        p.set_state(Vec5::new(0.0, 0.0, 0.0, 0.0, 0.0));
        p.advance(1e-3, &u);
        assert_eq!((p.crossing_searches(), p.mode_changes()), (0, 0));
        // The motor 0.1 pu faster than the load, 1 mrad from the driving edge: it is
        // reached within 34 µs and the gears engage.
        p.set_state(Vec5::new(0.003, 0.0, 0.1, 0.0, 0.0));
        p.advance(1e-3, &u);
        assert!(p.mode_changes() >= 1, "{}", p.mode_changes());
        assert!(
            p.crossing_searches() >= p.mode_changes(),
            "{} {}",
            p.crossing_searches(),
            p.mode_changes()
        );
    }
}

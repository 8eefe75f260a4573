//! The needle's contact with the tissue under the per-length friction model: a sub-grid
//! sheath of tissue around the shaft, elastic-plastic (Coulomb) friction in it, the tip's
//! cutting element, the contact patch that carries the tip's load before puncture, and the
//! tear that releases that load over a length of insertion.
//!
//! # Why a sheath
//!
//! An 18 G shaft (radius `a` = 0.635 mm) is far thinner than any node spacing `h`. The
//! tissue between the shaft's surface and the scale the nodes resolve (about `h / 2`) is
//! not represented by nodes, yet it is where the shaft's load goes in. Before this module
//! the needle nodes were held rigidly on the needle while they stuck (a kinematic
//! constraint that snapped their velocity to the needle's) and were released onto a
//! Coulomb force when they slipped; every switch and every node event jolted the resolved
//! tissue (measured on the liver scene: 711 steps with a force change above 5 %, a 470 Hz
//! ringing after every shaft node, a drop of the friction of one node length at every
//! addition).
//!
//! Here each needle node is tied to the needle through the sheath:
//!
//! - **Axial and circumferential shear** (friction). The shear displacement of the sheath
//!   of a shaft length `l` carries the force `phi = K (slip-free relative displacement)`
//!   with `K = k l`, `k` the shaft stiffness per unit length of a rigid cylinder in an
//!   elastic medium (Randolph and Wroth 1978, J Geotech Eng Div ASCE 104(GT12):1465-1488:
//!   shear stress `tau(r) = tau_0 a / r`, so `w(a) - w(r_m) = tau_0 a ln(r_m / a) / G`):
//!
//!   `k = 2 pi G / ln(r_m / a)`, `G = E / (2 (1 + nu))`, `r_m = h / 2`.
//!
//!   The resolved tissue carries the displacement beyond `r_m`; the sheath the rest. The
//!   force vector `(phi_axial, phi_circumferential)` is limited by the Coulomb cap
//!   `C = mu N` of the per-length friction model ([`crate::friction`]); beyond it the
//!   sheath slips (an elastic predictor and a radial return, as in elasto-plasticity:
//!   [`friction_step`]). The state is the force itself, not a stick/slip flag, so the
//!   force is a continuous function of the motion: no chatter, reversal unloads the
//!   sheath over the pre-sliding length `2 C / K` (about 2 mm in the liver scene), and
//!   the friction opposes the whole relative sliding velocity: spinning the needle at
//!   `omega` while pushing it at `v` leaves the axial part `C v / sqrt(v^2 + (omega a)^2)`
//!   in steady slip (Coulomb friction on a helical path; the same split is used for drill
//!   strings, Johancsik, Friesen and Dawson 1984, JPT 36(6):987-992).
//! - **Lateral**: the shaft holds every needle node on its line (bilateral, as in the
//!   paper); the normal force the node exerts goes to the needle and into the Coulomb
//!   cap.
//! - **Cutting** ([`front_step`]): the tip pushes the material at the crack front (the
//!   front needle node) with at most the cutting force `F_c` while it advances into
//!   tissue it has not cut; the force builds up over one needle radius of advance
//!   (stiffness `F_c / a`: the crack-tip process zone is of the size of the tip) and
//!   unloads elastically when the needle stops or turns back. It never pulls. Where its
//!   force depends on the node's place (those ramps, a dented membrane's punch) it has a
//!   dashpot of the sheath's loss, its stiffness times `eta / G`, solved implicitly with
//!   the node ([`front_viscosity`]); at the crack front itself it has none.
//! - **Contact before puncture** ([`Patch`]): the tip's load on an intact surface goes
//!   into a contact of radius `R_c` (`contact_radius`, by default the needle's radius; a
//!   capsule or skin under tension spreads it further). Its compliance is that of a rigid
//!   flat punch on an elastic half-space (Sneddon 1965, Int J Eng Sci 3:47-57):
//!   `(1 - nu^2) / (2 R_c E)`. The resolved tissue cannot carry a load that narrow (a
//!   point load on one node has no converged stiffness: its dent goes as `1 / h`), so the
//!   load is spread with a smooth weight over the surface nodes within a patch radius
//!   `R_p` the nodes resolve, and the sheath element in series supplies the compliance
//!   the patch lacks: the punch's minus the patch load's own half-space compliance
//!   (Boussinesq), computed for the actual nodes and weights ([`patch_compliance`]). The
//!   dent at a force then converges with refinement and depends on the tissue model only
//!   through its far field, to the extent that the lattice answers the patch as the
//!   continuum does, which takes a wide enough patch. With `R_p = max(2 h, 1.3 R_c)`
//!   (until 2026-11-27) the co-rotated Debunne lattice was stiffer than the Boussinesq
//!   estimate by a fixed share of a compliance that grows as `1 / h`: on the liver scene
//!   (1 N) the dent went as `7.97 mm - 4.7 mm^2 / h` (6.52, 6.97, 7.25 mm at 3.35, 4.71,
//!   6.42 mm spacing) and the mass-spring lattice was far softer (15.9 mm). Now `R_p =
//!   max(2 h, 1.3 R_c, min(4 h, R_f / 2))`, `R_f` the distance to the nearest mesh node
//!   off the surface the needle presses (its sides and back; the entry patch in
//!   `simulation/insertion.rs`): 8.23, 8.08 and 7.99 mm at 0.7, 1 and 1.4 times the
//!   liver's spacing (the coarsest has room for 3 of its 6.42 mm spacings only), against a
//!   punch on a half-space 7.97 mm and scikit-fem on the block 7.96 mm
//!   (`reference/needle_dent_fem.md`), and 8.08 / 8.19 / 8.01 / 9.36 / 9.18 mm for
//!   co-rotated Debunne, point based, neo-Hookean, shape matching and mass-spring (dev
//!   machine, CPU, 2026-11-27, the continuum models with the default hourglass control;
//!   7.94, 7.92, 7.75 and 7.92 / 8.00 / 7.87 mm with the first-order control at 4 before
//!   it). What it costs: the wider release at the puncture moves
//!   more tissue (with the first-order control: the liver's largest buzz 2.33%, at the
//!   end of the audit's 20 ms after the puncture, where it was 2.08% at a node removal;
//!   the layered scene's fell, 7.2% instead of 8.8%; with the default control, 2.28% and
//!   5.55%). With `R_p = 4 h` alone, a block a few spacings wide had its whole entry
//!   face as the patch, and the layered test block's GPU and CPU runs drifted apart by up
//!   to 140 steps at node events: `R_f / 2` keeps such a block at two spacings. Only the
//!   triangles facing the needle count (outward normal within 60 degrees of against it):
//!   a patch that reaches round the edge of a small body must not take its sides in.
//! - **Tear** ([`Tear`]): when a membrane gives, its stored load is not dropped in one
//!   step: the element's cap falls linearly to zero (to the cutting force at an inner
//!   membrane) as the tip advances `tear_length` into the tissue behind it (by default
//!   the length over which an 18-degree point opens the hole to the shaft's diameter).
//!
//! The node events of the paper's method (a node added at the tip or on the shaft, the Tip
//! node refreshed, a node removed) leave every element's force where it was: the
//! friction of the shaft is a field of force per length along the needle, and after an
//! edit each surviving node keeps its force per length while a new one takes the value
//! interpolated at its place, corrected so that the total does not change
//! ([`reassign`]); the cutting element and the patch are carried by whatever node is the
//! front. A node's Coulomb cap is its own tissue's, so the load the field gives it can
//! exceed it (a node of a softer layer taking a share of the load a gripping one
//! carried): what is above the cap at the edit is let go over
//! [`crate::handover::HANDOVER_TIME`] with the handover's fade, not clipped in one step
//! (`NeedleNode::carried`; measured on `layered_liver_biopsy.toml`, CPU, 2026-11-27: a
//! fat node added behind the skin took 56 mN against a cap of 17 mN, so 39 mN were
//! clipped at once, and with the node behind it, whose length the new one took, the
//! needle force fell 43 mN in one step, the scene's one jump; with the fade, none). The
//! excess is measured once after the edit and restarted only when a later edit leaves
//! more than what is left of it (the Tip refreshes of a fast needle, every few steps,
//! would otherwise keep it from fading). The needle force is therefore continuous across
//! every event. What an edit changes in the tissue's own elastic forces (the neighbour
//! rows it rewrites or puts back) is handed over in time by [`crate::handover`].

use glam::DVec3;

/// Shear modulus `E / (2 (1 + nu))`, Pa.
pub fn shear_modulus(young: f64, nu: f64) -> f64 {
    young / (2.0 * (1.0 + nu))
}

/// Axial shear stiffness per unit length of the tissue between a rigid shaft of radius
/// `radius` and the radius `spacing / 2` the nodes resolve, N/m^2 (module docs:
/// Randolph and Wroth 1978). The logarithm is kept at or above `ln 2` (the radius check
/// of the needle keeps `a < h / 2`; closer than that the sheath is thinner than the
/// shaft).
pub fn shaft_stiffness(young: f64, nu: f64, radius: f64, spacing: f64) -> f64 {
    let ratio = (0.5 * spacing / radius).max(2.0);
    2.0 * std::f64::consts::PI * shear_modulus(young, nu) / ratio.ln()
}

/// The sheath's viscous coefficient per unit length (N s/m^2) for a tissue of shear
/// viscosity `viscosity` (Pa s): the same logarithmic shear field as
/// [`shaft_stiffness`], `2 pi eta / ln(r_m / a)` (a Kelvin-Voigt solid's viscosity
/// enters where its shear modulus does).
pub fn shaft_viscosity(viscosity: f64, radius: f64, spacing: f64) -> f64 {
    let ratio = (0.5 * spacing / radius).max(2.0);
    2.0 * std::f64::consts::PI * viscosity / ratio.ln()
}

/// Compliance of a rigid flat punch of radius `radius` on an elastic half-space,
/// `(1 - nu^2) / (2 R E)`, m/N (Sneddon 1965).
pub fn punch_compliance(young: f64, nu: f64, radius: f64) -> f64 {
    (1.0 - nu * nu) / (2.0 * radius * young)
}

/// One step of a friction element (elastic predictor, radial return): the force
/// `force + increment` if its length is within `cap`, else scaled onto the cap. Returns
/// the force and whether it slips (sits on the cap).
pub fn friction_step(force: [f64; 2], increment: [f64; 2], cap: f64) -> ([f64; 2], bool) {
    let trial = [force[0] + increment[0], force[1] + increment[1]];
    let norm = trial[0].hypot(trial[1]);
    let cap = cap.max(0.0);
    if norm <= cap {
        (trial, false)
    } else {
        let s = cap / norm;
        ([trial[0] * s, trial[1] * s], true)
    }
}

/// One node's sheath over one step: the elastic force it carries (`elastic`, axial and
/// circumferential, N), the elastic increment of the relative motion not taken into it
/// yet (`K x` displacement: motion other than the integrator's, such as a node placed by
/// an edit), the needle's spin, and the axial motion the integrator will give the node
/// (`v' = free + beta * force`, relative to the needle).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SheathStep {
    /// Elastic force of the sheath at the last step, N.
    pub elastic: [f64; 2],
    /// Elastic increment not yet in `elastic`, N.
    pub increment: [f64; 2],
    /// Circumferential velocity of the needle's surface relative to the node (spin times
    /// the shaft's radius), m/s.
    pub spin: f64,
    /// The sheath's stiffness times the time step, N s/m: its elastic response to the
    /// relative motion over this step, taken implicitly (backward Euler).
    pub stiffness_dt: f64,
    /// Viscous coefficient of the sheath, N s/m.
    pub viscous: f64,
    /// The node's axial velocity relative to the needle at the end of the step without
    /// any force from the needle, m/s.
    pub free: f64,
    /// How much a force on the node changes that velocity, (m/s)/N: `D dt / m`.
    pub beta: f64,
    /// The tip's element's axial push on the node this step, N.
    pub other: f64,
    /// A dashpot beside `other`, N s/m: the tip's element resists the node's motion
    /// relative to the needle while it pushes, and never pulls (`other - c w >= 0`;
    /// [`front_viscosity`]). 0 for a node without one.
    pub other_viscous: f64,
    /// The needle's further axial pushes on the node, without a dashpot (the contact
    /// patch's share on the Surface node), N.
    pub patch: f64,
    /// Coulomb cap, N.
    pub cap: f64,
}

/// What [`sheath_step`] gives.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SheathOut {
    /// The sheath's elastic force after the step, N (axial, circumferential).
    pub elastic: [f64; 2],
    /// Its force on the node, N (axial, circumferential).
    pub force: [f64; 2],
    /// Whether the slider slips.
    pub slips: bool,
    /// The node's axial velocity relative to the needle at the end of the step, m/s
    /// (what the integrator gives it under `force`).
    pub velocity: f64,
    /// The pushes on the node with the element's dashpot, `other - c w + patch`, N (the
    /// element's part 0 where its dashpot would pull: it lets go).
    pub other: f64,
}

/// The Kelvin-Voigt sheath (spring `K`, dashpot `c`, on both the axial and the
/// circumferential relative motion) with a Coulomb slider in series. While the slider
/// holds, the force is the spring's plus the dashpot's on the relative velocity at the
/// end of the step; above the cap it slips, the force is the cap along the trial force,
/// and the Kelvin-Voigt element relaxes towards it (`K x + c x' = F`: in steady slip the
/// dashpot carries nothing, so there is no rate effect on steady sliding, and the slip
/// direction is that of the relative velocity, spin included).
///
/// Both the spring and the dashpot act on the relative velocity at the end of the step
/// (backward Euler, solved with the node's own update). A spring loaded with the
/// displacement of the step before lags the motion by a step, which is a negative
/// damping of `K dt` (measured on the liver scene at 10 mm spacing, `K` 170 N/m, `dt`
/// 0.59 ms: it cancelled the sheath's viscosity); implicit, the sheath only dissipates.
/// An earlier form folded the dashpot's force into the spring's state on every slipping
/// step, which counted the axial velocity twice and turned the friction of a spinning
/// needle towards the axis (an axial share of 0.87 where Coulomb friction on the helix
/// gives 0.78).
///
/// The push `other` (the tip's element) may come with a dashpot `other_viscous` on the
/// same relative velocity, taken implicitly too; where it would pull (the node running
/// away from the tip faster than the push can follow) the element lets go for the step:
/// push and dashpot both 0.
pub fn sheath_step(s: &SheathStep) -> SheathOut {
    let out = sheath_step_with(s, s.other, s.other_viscous);
    if out.other - s.patch >= 0.0 || s.other_viscous == 0.0 {
        return out;
    }
    sheath_step_with(s, 0.0, 0.0)
}

/// [`sheath_step`] with the push `other` and its dashpot `c`.
fn sheath_step_with(s: &SheathStep, other: f64, c: f64) -> SheathOut {
    let e0 = [s.elastic[0] + s.increment[0], s.elastic[1] + s.increment[1]];
    let resist = s.viscous + s.stiffness_dt;
    let other = other + s.patch;
    let w = (s.free + s.beta * (other + e0[0])) / (1.0 + s.beta * (resist + c));
    let held = [e0[0] - resist * w, e0[1] + resist * s.spin];
    let (force, slips) = friction_step(held, [0.0, 0.0], s.cap);
    if !slips {
        return SheathOut {
            elastic: [e0[0] - s.stiffness_dt * w, e0[1] + s.stiffness_dt * s.spin],
            force,
            slips,
            velocity: w,
            other: other - c * w,
        };
    }
    let velocity = (s.free + s.beta * (other + force[0])) / (1.0 + s.beta * c);
    // K x_new + c (x_new - x_0) / dt = F, in force units e = K x.
    let r = match s.stiffness_dt > 0.0 {
        true => s.viscous / s.stiffness_dt,
        false => 0.0,
    };
    SheathOut {
        elastic: [
            (force[0] + r * e0[0]) / (1.0 + r),
            (force[1] + r * e0[1]) / (1.0 + r),
        ],
        force,
        slips,
        velocity,
        other: other - c * velocity,
    }
}

/// The dashpot of the tip's element (N s/m): its stiffness `k` (N/m; the cutting
/// element's `F_c / a`, a dented membrane's punch) times the tissue's own relaxation time
/// in the sheath, `eta / G` (the sheath's viscous over its elastic coefficient per unit
/// length, [`shaft_viscosity`] over [`shaft_stiffness`]: the same logarithmic factor
/// cancels). The element is tissue at the crack tip, so it has the sheath's loss.
///
/// Why: the front node is a lump of the tissue ahead (a 3 mm node of fat weighs 25 mg)
/// on the element's ramps (0.3-0.5 N over one needle radius, 500-800 N/m), a mode near
/// 1 kHz that nothing else damped while the node slips (the sheath's own dashpot is capped
/// off then). It shows where the tissue ahead of the tip moves with the needle and springs
/// forward. Measured with `needlesim run` and `force_audit.py` (CPU, 2026-11-27), without
/// and with this dashpot: the layered scene's largest buzz 6.29% and 6.12%; a variant of
/// it twice as wide (sides 30 mm from the needle, first 1.6 s) 16 and 6 jumps; with
/// far-field sides at 15 mm ([`needlesim_core::boundary`]) 5 and 3 jumps, 13.6% and 9.8%
/// of buzz; the liver 1.77% and 1.76%; the paper scenes, the phantom and
/// `needle_insert_extract` unchanged. A dashpot on the node's whole motion relative to the
/// needle (the crack front included) acted on the insertion speed itself: a viscous
/// cutting force that stepped by 15 mN (5.7%) at the paper scenes' first Shaft node.
pub fn front_viscosity(stiffness: f64, sheath_viscous: f64, sheath_stiffness: f64) -> f64 {
    match sheath_stiffness > 0.0 && stiffness.is_finite() {
        true => stiffness * sheath_viscous / sheath_stiffness,
        false => 0.0,
    }
}

/// One step of a pushing element (the tip's cutting element, the contact patch): `force +
/// increment` clamped to `[0, cap]` (it pushes the tissue ahead, never pulls).
pub fn front_step(force: f64, increment: f64, cap: f64) -> f64 {
    (force + increment).clamp(0.0, cap.max(0.0))
}

/// Crack speed of a membrane that gave, as a share of the tissue's shear-wave speed, in
/// [`tear_time`].
///
/// A dynamic crack in an elastic solid runs below the Rayleigh wave speed, about 0.95
/// `c_s` at nu near 0.5 (L. B. Freund, Dynamic Fracture Mechanics, Cambridge 1990). The
/// share is our choice, not a measurement: a quarter gives the liver's 2.5 mm contact
/// 3.9 ms, near the 4 ms the liver scene was tuned to by its needle force until
/// 2026-11-27 (it takes a third since: [`tear_time`]), and carries that choice to other
/// materials and contacts through what sets the time: the wave speed and the width of
/// the loaded surface.
pub const TEAR_SPEED_SHARE: f64 = 0.25;

/// An estimate of a membrane's tear time (s), for the `tear_time` key: the time a crack
/// running at [`TEAR_SPEED_SHARE`] of the shear-wave speed `c_s = sqrt(G / rho)`, `G = E
/// / (2 (1 + nu))`, takes to cross the contact radius `contact_radius` that carried the
/// load, `t = R_c / (0.25 c_s)`; `None` unless the modulus, density and radius are
/// positive and the time finite.
///
/// Liver (E 20 kPa, nu 0.45, 1,060 kg/m^3, R_c 2.5 mm): 3.9 ms; the paper's cube (E
/// 10 kPa, an 18 G needle's radius): 1.4 ms. The paper scenes, `needle_insert_extract`
/// and the phantom scene set their `tear_time` from it; the layered scene keeps 4 ms in
/// every layer (its skin would take 1.4 ms and ring harder); the liver scenes take a
/// third of the wave speed, 2.9 ms (with 4 ms the drop at the puncture still read 2.33%
/// of buzz 20 ms after it, where the audit stops exempting it: their comment). It is not
/// the default (15 ms), measured (dev machine, CPU, 2026-11-27): in elastic tissue
/// without the Kelvin-Voigt viscosity the fast release can make the tissue behind the
/// tip recoil and chatter along the shaft (`tests/layers.rs`'s friction
/// slope block: the first layer's slope 7.9 N/m instead of 6.5 with 15 ms, the force
/// dipping to half for the next 2 mm), while the four `paper_insertion_*` scenes (damped
/// by `physics.damping`, their force audited as `shared/tools/force_audit.py` does) read
/// a largest buzz of 1.1-2.0% with it (`needlesim report --realism --full`, before the
/// run's last 20 ms) against 7.3-11.0% with 15 ms, which rings on past the audit's 20 ms
/// after the puncture.
pub fn tear_time(contact_radius: f64, (young, nu): (f64, f64), density: f64) -> Option<f64> {
    let shear = young / (2.0 * (1.0 + nu));
    let t = contact_radius / (TEAR_SPEED_SHARE * (shear / density).sqrt());
    (shear > 0.0 && density > 0.0 && contact_radius > 0.0 && t.is_finite() && t > 0.0).then_some(t)
}

/// A membrane that gave: its element's cap falls linearly from `from` to `to` as the crack
/// front advances `length` past `at` (depths along the needle, m) or as `time` passes
/// since `started` (s), whichever is further on.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Tear {
    /// The force when the membrane gave, N.
    pub from: f64,
    /// The cap once torn through, N (the cutting force behind an inner membrane, 0 for the
    /// entry patch).
    pub to: f64,
    /// Crack front depth when it gave, m.
    pub at: f64,
    /// Tear length, m.
    pub length: f64,
    /// Simulated time when it gave, s.
    pub started: f64,
    /// Tear time, s.
    pub time: f64,
}

impl Tear {
    /// How far through the tear is (0 to 1) with the crack front at depth `front` at time
    /// `now`.
    pub fn progress(&self, front: f64, now: f64) -> f64 {
        let by_length = (front - self.at) / self.length;
        let by_time = (now - self.started) / self.time;
        by_length.max(by_time).clamp(0.0, 1.0)
    }

    /// The cap with the crack front at depth `front` at time `now`.
    pub fn cap(&self, front: f64, now: f64) -> f64 {
        self.from + (self.to - self.from) * self.progress(front, now)
    }

    /// A crossing into a region without a membrane (the cutting force blended over the
    /// point's length, no time bound), not a membrane tearing.
    pub fn is_crossing(&self) -> bool {
        self.time == f64::MAX
    }

    /// Whether the tear is through.
    pub fn done(&self, front: f64, now: f64) -> bool {
        self.progress(front, now) >= 1.0
    }
}

/// The tip's element at the crack front (cutting, denting an inner membrane, tearing
/// through it), carried by whichever needle node is the front.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize, serde::Deserialize)]
pub struct FrontElement {
    /// Force the tip exerts on the material ahead, N (>= 0).
    pub force: f64,
    /// An inner membrane being torn through.
    pub tear: Option<Tear>,
    /// While it dents an inner membrane: how far the tip is into the membrane's dent
    /// below the resolved tissue (the element's compression, force over stiffness), m;
    /// the material the tip presses on is that far behind it. 0 otherwise.
    pub dent: f64,
    /// The share of the element that pushed in the last step (1 while the front node is
    /// at the tip's face, falling to 0 as the tissue carries it on ahead); `None` before
    /// the first step at a crack front.
    #[serde(default)]
    pub free: Option<f64>,
    /// A node edit's change of that share, being handed over ([`FreeFade`]).
    #[serde(default)]
    pub free_fade: Option<FreeFade>,
}

/// The change a node edit made to the share of the tip's element that pushes, handed
/// over in time (issue 39: node events the force does not see).
///
/// Where the tissue ahead gives way (a soft layer behind a stiffer one, a layer that moves
/// with the needle), the front node is carried ahead of the tip's face and the element
/// lets go of it over a refresh distance. An edit at the tip (a node added, the Tip node
/// refreshed) puts a node back at the face, and the share went from what the carried node
/// had to 1 in one step: on `layered_liver_biopsy.toml` (CPU, 2026-11-28) the tip force
/// went 0.194 -> 0.300 N at a node addition in the muscle and the needle force jumped
/// 0.115 N, the run's one jump. The share after an edit is now `own + offset * fade(t)`,
/// `own` the share of the node at the front, `offset` the share before the edit less the
/// new front node's own, faded out as the edit's elastic change is
/// ([`crate::handover::fade`], over the same time): continuous at the edit, the new node's
/// own share once the fade is over. Every edit of a step starts one (a new fade takes
/// over what is left of a running one and lasts at least as long); a step without a
/// crack front (Touching, the tip out of the body) drops the share and its fade.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct FreeFade {
    /// The share before the edit less the share of the node after it.
    pub offset: f64,
    /// Simulated time of the edit, s.
    pub started: f64,
    /// How long it is handed over, s.
    pub duration: f64,
}

impl FreeFade {
    /// The fade an edit at time `now` starts: from the share `last` of the step before
    /// (which holds what is left of a running fade, `previous`) to the new front node's
    /// `own`, over `duration` or what is left of `previous`, whichever is longer (as
    /// [`crate::handover::Handover::start`] merges elastic handovers); `None` without a
    /// share before.
    pub fn start(
        last: Option<f64>,
        own: f64,
        previous: Option<&FreeFade>,
        now: f64,
        duration: f64,
    ) -> Option<FreeFade> {
        let left = previous
            .map_or(0.0, |f| f.started + f.duration - now)
            .max(0.0);
        last.map(|last| FreeFade {
            offset: last - own,
            started: now,
            duration: duration.max(left),
        })
    }

    /// What is left of the offset at time `now`.
    pub fn at(&self, now: f64) -> f64 {
        self.offset * crate::handover::fade(now - self.started, self.duration)
    }

    /// Whether the fade is over at time `now`.
    pub fn done(&self, now: f64) -> bool {
        now - self.started >= self.duration
    }
}

/// The contact patch of the tip on the entry surface (Touching) and, after puncture,
/// while the entry membrane tears.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Patch {
    /// Mesh nodes of the patch (surface nodes near the contact point).
    pub nodes: Vec<u32>,
    /// Their weights; with `surface` they sum to 1.
    pub weights: Vec<f64>,
    /// Weight of the Surface node (needle node 0).
    pub surface: f64,
    /// Stiffness of the sub-grid element in series, N/m.
    pub stiffness: f64,
    /// Weighted axial coordinate of the patch in the needle frame at the last step, m
    /// (`None` before the first step).
    pub mean: Option<f64>,
    /// Where the surface point the needle touched sits against that mean, along the
    /// needle, at the first step (m): the Surface node's axial coordinate less the mean.
    /// The tip has drawn back off the patch when it is behind `mean + offset`. The mean
    /// alone is not the touched point: on a surface the needle meets at an angle, the
    /// patch's nodes lie at different depths along the needle, and their weighted mean
    /// sat up to a few tenths of a millimetre ahead of the tip at first touch, so a
    /// needle 10 degrees off the normal let go of the surface in its second step and
    /// passed through the tissue untouched (found 2026-11-28, the liver scene tilted by
    /// 10 degrees). It is kept from that first step: a needle turned while it dents the
    /// surface moves the touched point against the mean by the patch's lever arm times
    /// the turn, which this does not follow.
    #[serde(default)]
    pub offset: f64,
    /// Force of the tip on the patch, N (>= 0).
    pub force: f64,
    /// The entry membrane tearing (after puncture).
    pub tear: Option<Tear>,
}

/// Smooth patch weight of a node at distance `r` from the contact point, patch radius
/// `radius`: `(1 - (r / R)^2)^2` inside, 0 outside (not normalised).
pub fn patch_weight(r: f64, radius: f64) -> f64 {
    if r >= radius {
        0.0
    } else {
        let q = r / radius;
        (1.0 - q * q).powi(2)
    }
}

/// The half-space compliance of a load shared by surface points with weights `w` (sum 1)
/// at rest positions `x`, each spread over its surface cell of area `area` (m^2): the
/// work-conjugate mean displacement per unit force, m/N. Pairs interact through the
/// Boussinesq point-load solution `(1 - nu^2) / (pi E r)`; a point's own cell counts as a
/// uniformly loaded disk of the same area, whose mean displacement is
/// `16 (1 - nu^2) / (3 pi^2 E R)` (Timoshenko and Goodier, Theory of Elasticity, 1970,
/// section 138).
///
/// Two points closer than `rho = 3 pi R / 16` (`R` the radius of a disk of their mean
/// cell's area; `rho` is about a third of a spacing on a lattice face) count as
/// overlapping cells: their pair term is
/// held at `(1 - nu^2) / (pi E rho)`, the self term of such a cell, instead of growing as
/// `1 / r`. The Surface node is put where the needle's axis meets the surface, so it can
/// sit next to a lattice node; with the point-load term the pair of them made the
/// resolved compliance large, the sub-grid element was cut to its floor and the dent at
/// the puncture force came out a third of what it is a spacing away (gel phantom, 10 mm
/// spacing, 1 N: 2.58 mm with the axis through a node, 5.27 mm 0.5 mm from it, 7.66 mm
/// between nodes; dev machine, 2026-11-28). Lattice neighbours, a spacing apart or more,
/// keep the point-load term.
pub fn patch_compliance(young: f64, nu: f64, x: &[DVec3], w: &[f64], area: &[f64]) -> f64 {
    let c = (1.0 - nu * nu) / young;
    let pi = std::f64::consts::PI;
    let radius = |a: f64| (a.max(1e-30) / pi).sqrt();
    let mut total = 0.0;
    for i in 0..x.len() {
        for j in 0..x.len() {
            let g = if i == j {
                16.0 * c / (3.0 * pi * pi * radius(area[i]))
            } else {
                let mean = (0.5 * (area[i] + area[j])).max(1e-30);
                let rho = 3.0 * pi / 16.0 * radius(mean);
                c / (pi * x[i].distance(x[j]).max(rho))
            };
            total += w[i] * w[j] * g;
        }
    }
    total
}

/// Number of per-length quantities [`reassign`] carries along the shaft.
pub const FIELD: usize = 5;

/// A node of the shaft's load field before an edit: axial coordinate `s` (m) and its
/// loads per unit length (N/m): axial and circumferential friction, then the normal force
/// of the tissue on the shaft (world frame).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FieldPoint {
    /// Axial coordinate, m.
    pub s: f64,
    /// Loads per length, N/m: axial friction, circumferential friction, normal x, y, z.
    pub per_length: [f64; FIELD],
}

/// The loads of the nodes after an edit, so that the shaft's load field is continuous:
/// node `k` (axial coordinate `s[k]`, shaft length `l[k]`) keeps its own load per length
/// when `own[k]` is `Some`, otherwise takes the field `before` interpolated (linearly in
/// `s`, held at the ends) at `s[k]`; then the new nodes (or, without any, all nodes) share
/// the difference to `total` (the summed loads before) in proportion to their length.
/// Returns the loads per node, N.
pub fn reassign(
    before: &[FieldPoint],
    total: [f64; FIELD],
    s: &[f64],
    l: &[f64],
    own: &[Option<[f64; FIELD]>],
) -> Vec<[f64; FIELD]> {
    let interp = |x: f64| -> [f64; FIELD] {
        let Some(first) = before.first() else {
            return [0.0; FIELD];
        };
        let last = before.last().expect("non-empty");
        if x <= first.s {
            return first.per_length;
        }
        if x >= last.s {
            return last.per_length;
        }
        let i = before.partition_point(|p| p.s <= x);
        let (a, b) = (before[i - 1], before[i]);
        let f = if b.s > a.s {
            (x - a.s) / (b.s - a.s)
        } else {
            0.0
        };
        std::array::from_fn(|c| a.per_length[c] + f * (b.per_length[c] - a.per_length[c]))
    };
    let mut out: Vec<[f64; FIELD]> = (0..s.len())
        .map(|k| {
            let per = own[k].unwrap_or_else(|| interp(s[k]));
            per.map(|p| p * l[k])
        })
        .collect();
    let fresh: Vec<usize> = (0..s.len()).filter(|&k| own[k].is_none()).collect();
    let share: Vec<usize> = if fresh.iter().any(|&k| l[k] > 0.0) {
        fresh
    } else {
        (0..s.len()).collect()
    };
    let length: f64 = share.iter().map(|&k| l[k]).sum();
    if length > 0.0 {
        for c in 0..FIELD {
            let now: f64 = out.iter().map(|f| f[c]).sum();
            let d = total[c] - now;
            for &k in &share {
                out[k][c] += d * l[k] / length;
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The tear-time estimate against the closed form for the liver (G = E / 2.9, c_s =
    /// sqrt(G / rho) = 2.551 m/s, 2.5 mm at 0.638 m/s: 3.920 ms), scaling as R_c and as
    /// 1 / sqrt(E), and `None` for a missing modulus, density or radius.
    #[test]
    fn tear_time_is_the_contact_over_a_quarter_of_the_shear_wave_speed() {
        let t = tear_time(0.0025, (20e3, 0.45), 1060.0).unwrap();
        assert!((t - 3.920e-3).abs() < 1e-6, "{t}");
        let twice = tear_time(0.005, (20e3, 0.45), 1060.0).unwrap();
        assert!((twice / t - 2.0).abs() < 1e-12);
        let stiffer = tear_time(0.0025, (80e3, 0.45), 1060.0).unwrap();
        assert!((stiffer / t - 0.5).abs() < 1e-12);
        assert_eq!(tear_time(0.0025, (0.0, 0.0), 1060.0), None);
        assert_eq!(tear_time(0.0025, (20e3, 0.45), 0.0), None);
        assert_eq!(tear_time(0.0, (20e3, 0.45), 1060.0), None);
        assert_eq!(tear_time(0.0025, (f64::NAN, 0.45), 1060.0), None);
        assert_eq!(tear_time(f64::INFINITY, (20e3, 0.45), 1060.0), None);
        assert_eq!(tear_time(0.0025, (20e3, 0.45), f64::INFINITY), None);
    }

    #[test]
    fn friction_element_sticks_slips_and_reverses_without_a_jump() {
        let cap = 1.0;
        // Loading by 0.3 N a step: elastic up to the cap, then on it.
        let mut f = [0.0, 0.0];
        let mut slips = Vec::new();
        for _ in 0..5 {
            let (g, s) = friction_step(f, [0.3, 0.0], cap);
            f = g;
            slips.push(s);
        }
        assert_eq!(f, [1.0, 0.0]);
        assert_eq!(slips, [false, false, false, true, true]);
        // Reversal: the force unloads by the increment, never by more.
        let (g, s) = friction_step(f, [-0.3, 0.0], cap);
        assert!((g[0] - 0.7).abs() < 1e-15 && !s);
        // Sliding on a helix: the cap is shared, the axial part is v / |w| of it.
        let mut f = [0.0, 0.0];
        for _ in 0..100 {
            f = friction_step(f, [0.3, 0.4], cap).0;
        }
        assert!(
            (f[0] - 0.6).abs() < 1e-12 && (f[1] - 0.8).abs() < 1e-12,
            "{f:?}"
        );
    }

    #[test]
    fn viscous_sheath_is_implicit_and_vanishes_in_steady_slip() {
        // A node moving at 1 m/s relative to the needle with no other force: a very
        // stiff dashpot stops it within the step (no overshoot, however large c).
        let step = |elastic: [f64; 2], viscous: f64, stiffness_dt: f64, cap: f64| {
            sheath_step(&SheathStep {
                elastic,
                increment: [0.0; 2],
                spin: 0.0,
                stiffness_dt,
                viscous,
                free: 1.0,
                beta: 1e-3,
                other: 0.0,
                other_viscous: 0.0,
                patch: 0.0,
                cap,
            })
        };
        for c in [1.0, 1e3, 1e9] {
            let o = step([0.0; 2], c, 1e-3, f64::INFINITY);
            let after = 1.0 + 1e-3 * o.force[0];
            assert!(!o.slips && (0.0..=1.0).contains(&after), "c {c}: {after}");
            assert!((o.velocity - after).abs() < 1e-12, "{o:?}");
        }
        // Capped, the dashpot adds nothing beyond the cap, and in steady slip the spring
        // comes to carry the whole cap.
        let mut e = [0.0; 2];
        for _ in 0..100 {
            let o = step(e, 1.0, 1.0, 0.5);
            assert!(
                o.slips && (o.force[0] + 0.5).abs() < 1e-12 && o.force[1] == 0.0,
                "{o:?}"
            );
            e = o.elastic;
        }
        assert!((e[0] + 0.5).abs() < 1e-3, "{e:?}");
    }

    #[test]
    fn the_push_dashpot_is_implicit_and_never_pulls() {
        let step = |free: f64, other_viscous: f64| {
            sheath_step(&SheathStep {
                elastic: [0.0; 2],
                increment: [0.0; 2],
                spin: 0.0,
                stiffness_dt: 1e-3,
                viscous: 0.0,
                free,
                beta: 1.0,
                other: 0.5,
                other_viscous,
                patch: 0.0,
                cap: f64::INFINITY,
            })
        };
        // Without a dashpot the push is `other` exactly (bitwise the former step).
        let plain = step(-1.0, 0.0);
        assert_eq!(plain.other, 0.5);
        // A node closing on the tip: the dashpot adds to the push, and however stiff it
        // is, the node is not thrown back (implicit: its relative velocity stays between
        // the free one and zero).
        for c in [1.0, 1e3, 1e9] {
            let o = step(-1.0, c);
            assert!(o.other > 0.5, "c {c}: {o:?}");
            assert!((-1.0..=0.0).contains(&o.velocity), "c {c}: {o:?}");
            let expected = -1.0 + (o.other + o.force[0]);
            assert!((o.velocity - expected).abs() < 1e-9 * (1.0 + c), "{o:?}");
        }
        // A node running away from the tip: the element lets go rather than pull.
        let o = step(10.0, 1e3);
        assert_eq!(o.other, 0.0, "{o:?}");
        assert!(o.velocity > 0.0);
        // The element's dashpot is its stiffness times the sheath's eta / G.
        assert!((front_viscosity(600.0, 2.0, 4000.0) - 0.3).abs() < 1e-12);
        assert_eq!(front_viscosity(600.0, 2.0, 0.0), 0.0);
    }

    #[test]
    fn spinning_slip_follows_the_helix_at_any_viscosity() {
        // Steady slip at 5 mm/s axially with the shaft's surface turning at 4 mm/s: the
        // axial share of the friction is v / |(v, omega a)|, with or without a dashpot.
        let (v, spin) = (5e-3, 4e-3);
        for viscous in [0.0, 0.1, 10.0] {
            let mut e = [0.0; 2];
            let mut f = [0.0; 2];
            for _ in 0..20000 {
                let o = sheath_step(&SheathStep {
                    elastic: e,
                    increment: [0.0; 2],
                    spin,
                    stiffness_dt: 0.1,
                    viscous,
                    // A heavy node held still: relative velocity -v whatever the force.
                    free: -v,
                    beta: 0.0,
                    other: 0.0,
                    other_viscous: 0.0,
                    patch: 0.0,
                    cap: 1.0,
                });
                e = o.elastic;
                f = o.force;
            }
            // The node is dragged along the needle and round with its surface.
            assert!(f[0] > 0.0 && f[1] > 0.0, "{f:?}");
            let share = f[0] / f[0].hypot(f[1]);
            let helix = v / v.hypot(spin);
            assert!(
                (share - helix).abs() < 1e-6,
                "c {viscous}: {share} vs {helix}"
            );
        }
    }

    #[test]
    fn implicit_sheath_spring_damps_a_node_instead_of_feeding_it() {
        // A 1 g node on a 200 N/m sheath, released from 10 um with dt 0.6 ms and no
        // other damping. Loaded with the displacement of the step before (the old form),
        // the spring's lag is a negative damping K dt and the swing grows; backward Euler
        // (this form) only dissipates. Energies over 200 steps (about 9 periods).
        let (k, m, dt) = (200.0, 1e-3, 6e-4);
        let energy = |x: f64, v: f64| 0.5 * k * x * x + 0.5 * m * v * v;
        let start = energy(1e-5, 0.0);
        let (mut x, mut v, mut f) = (1e-5, 0.0, -k * 1e-5);
        let mut peak = 0.0f64;
        for _ in 0..200 {
            let o = sheath_step(&SheathStep {
                elastic: [f, 0.0],
                increment: [0.0; 2],
                spin: 0.0,
                stiffness_dt: k * dt,
                viscous: 0.0,
                free: v,
                beta: dt / m,
                other: 0.0,
                other_viscous: 0.0,
                patch: 0.0,
                cap: f64::INFINITY,
            });
            v = o.velocity;
            x += dt * v;
            f = o.elastic[0];
            assert!(
                (f + k * x).abs() < 1e-9 * k * 1e-5,
                "spring and motion agree"
            );
            peak = peak.max(energy(x, v));
        }
        let implicit = energy(x, v);
        assert!(
            peak <= start * (1.0 + 1e-9),
            "never above the start: {peak} {start}"
        );
        assert!(implicit < 0.5 * start, "decays: {start} -> {implicit}");
        // The lagged spring on the same node.
        let (mut x, mut v, mut lagged) = (1e-5, 0.0, 1e-5);
        for _ in 0..200 {
            v += dt * (-k * lagged) / m;
            lagged = x;
            x += dt * v;
        }
        assert!(
            energy(x, v) > 2.0 * start,
            "the lag feeds it: {}",
            energy(x, v)
        );
    }

    #[test]
    fn front_element_pushes_up_to_its_cap_and_never_pulls() {
        assert_eq!(front_step(0.2, 0.5, 0.3), 0.3);
        assert_eq!(front_step(0.2, -0.5, 0.3), 0.0);
        assert_eq!(front_step(0.2, 0.05, 0.3), 0.25);
    }

    #[test]
    fn tear_cap_falls_linearly_over_its_length_or_its_time() {
        let t = Tear {
            from: 2.0,
            to: 0.5,
            at: 0.01,
            length: 0.002,
            started: 1.0,
            time: 0.01,
        };
        // By the advance, the clock standing still...
        assert_eq!(t.cap(0.009, 1.0), 2.0);
        assert!((t.cap(0.011, 1.0) - 1.25).abs() < 1e-12);
        assert_eq!(t.cap(0.02, 1.0), 0.5);
        assert!(!t.done(0.0119, 1.0) && t.done(0.012, 1.0));
        // ... or by the clock, the needle standing still: whichever is further.
        assert!((t.cap(0.01, 1.005) - 1.25).abs() < 1e-12);
        assert!((t.cap(0.0115, 1.0025) - 0.875).abs() < 1e-12);
        assert!(t.done(0.01, 1.01));
    }

    #[test]
    fn stiffnesses_follow_their_closed_forms() {
        // Randolph and Wroth: 2 pi G / ln(r_m / a) with r_m = h / 2.
        let (e, nu, a, h) = (20e3, 0.45, 0.635e-3, 5e-3);
        let g = e / 2.9;
        let k = shaft_stiffness(e, nu, a, h);
        assert!((k - 2.0 * std::f64::consts::PI * g / (2.5e-3f64 / a).ln()).abs() < 1e-9 * k);
        // Sneddon: a 1 mm punch into 20 kPa, nu 0.5: 0.75 / 40 = 18.75 mm/N.
        assert!((punch_compliance(20e3, 0.5, 1e-3) - 0.01875).abs() < 1e-15);
    }

    #[test]
    fn one_point_patch_is_the_uniform_disk_and_far_points_add_boussinesq() {
        let (e, nu) = (1e4, 0.3);
        let c = (1.0 - nu * nu) / e;
        let area = std::f64::consts::PI * 1e-6; // a disk of radius 1 mm
        let one = patch_compliance(e, nu, &[DVec3::ZERO], &[1.0], &[area]);
        let disk = 16.0 * c / (3.0 * std::f64::consts::PI.powi(2) * 1e-3);
        assert!((one - disk).abs() < 1e-9 * disk);
        // Two far points sharing the load: each self term weighs 1/4, the pair 2 x 1/4.
        let x = [DVec3::ZERO, DVec3::new(1.0, 0.0, 0.0)];
        let two = patch_compliance(e, nu, &x, &[0.5, 0.5], &[area, area]);
        let expect = 0.5 * disk + 0.5 * c / std::f64::consts::PI;
        assert!((two - expect).abs() < 1e-9 * expect);
    }

    #[test]
    fn a_free_fade_starts_at_its_offset_and_is_gone_after_its_time() {
        let f = FreeFade {
            offset: -0.4,
            started: 1.0,
            duration: 0.04,
        };
        assert_eq!(f.at(1.0), -0.4);
        assert!(!f.done(1.0));
        // Half way the smoothstep is at one half; the rate is continuous at both ends.
        assert!((f.at(1.02) + 0.2).abs() < 1e-12);
        assert!((f.at(1.0 + 1e-6) + 0.4).abs() < 1e-8);
        assert!(f.at(1.04 - 1e-6).abs() < 1e-8);
        assert_eq!(f.at(1.05), 0.0);
        assert!(f.done(1.04) && f.done(1.05));
    }

    #[test]
    fn points_closer_than_their_cells_count_as_overlapping_cells() {
        let (e, nu) = (1e4, 0.3);
        let area = std::f64::consts::PI * 1e-6; // disks of radius 1 mm
        let one = patch_compliance(e, nu, &[DVec3::ZERO], &[1.0], &[area]);
        // Two coincident points sharing the load are the one disk, not a singular pair.
        let x = [DVec3::ZERO, DVec3::ZERO];
        let same = patch_compliance(e, nu, &x, &[0.5, 0.5], &[area, area]);
        assert!((same - one).abs() < 1e-9 * one, "{same} vs {one}");
        // Continuous where the pair term takes over: at and just past rho.
        let rho = 3.0 * std::f64::consts::PI / 16.0 * 1e-3;
        let at = |r: f64| {
            let x = [DVec3::ZERO, DVec3::new(r, 0.0, 0.0)];
            patch_compliance(e, nu, &x, &[0.5, 0.5], &[area, area])
        };
        assert!((at(rho) - at(rho * (1.0 + 1e-9))).abs() < 1e-6 * at(rho));
        assert!((at(0.1 * rho) - at(rho)).abs() < 1e-12 * at(rho));
        assert!(at(2.0 * rho) < at(rho));
    }

    #[test]
    fn reassignment_keeps_the_total_and_interpolates_new_nodes() {
        // Two nodes at 0 and 2 with 1 and 3 N/m; a new node at 1 between them.
        let p = |a: f64, c: f64| [a, c, 0.0, 0.0, 0.0];
        let before = [
            FieldPoint {
                s: 0.0,
                per_length: p(1.0, 0.0),
            },
            FieldPoint {
                s: 2.0,
                per_length: p(3.0, 0.5),
            },
        ];
        let total = p(1.0 * 1.0 + 3.0 * 1.0, 0.5);
        let s = [0.0, 1.0, 2.0];
        let l = [0.5, 1.0, 0.5];
        let own = [Some(p(1.0, 0.0)), None, Some(p(3.0, 0.5))];
        let f = reassign(&before, total, &s, &l, &own);
        let sum: f64 = f.iter().map(|x| x[0]).sum();
        assert!((sum - total[0]).abs() < 1e-12, "{f:?}");
        let sum_c: f64 = f.iter().map(|x| x[1]).sum();
        assert!((sum_c - total[1]).abs() < 1e-12, "{f:?}");
        // The trapezoid rule integrates the linear field exactly: the new node takes
        // exactly its interpolated 2 N/m.
        assert!((f[1][0] - 2.0).abs() < 1e-12, "{f:?}");
        // A removal: the survivors share what the removed node carried.
        let f = reassign(&before, p(10.0, 0.0), &[0.0], &[1.0], &[Some(p(1.0, 0.0))]);
        assert_eq!(f, vec![p(10.0, 0.0)]);
    }
}

//! Weighted mass-spring model (MSM), paper section 4.
//!
//! One spring per mutual neighbour pair (i, j) with rest length `L_ij = |x0_j - x0_i|`:
//!
//! `f_i += w_ij [k (|d| - L_ij) + c (v_j - v_i) . d^] d^`,  `d = x_j - x_i`, `d^ = d / |d|`
//!
//! with stiffness k (N/m) and spring damping c (N s/m). Forces are gathered per node, each
//! pair evaluated from both ends with the same bits, so for mutual lists with symmetric
//! weights the forces sum to zero (momentum is conserved). A pair whose nodes coincide
//! (`|d| = 0`) has no direction and contributes nothing.
//!
//! Spring shares (`spring_share = "cell"`, the default): the weight `w_ij` is the kernel
//! weight times `max(V_i, V_j) / a^3`, `V` the nodes' cells and `a` the lattice spacing.
//! On a box lattice that is the fraction of the lattice cells around the spring that lie
//! inside the body (1 inside, 1/2 in a face, 1/4 along an edge), so the energy of a
//! uniform strain is the bulk lattice's energy density times the body's volume and the
//! calibration `k = C E h` does not drift with resolution. Springs of nodes added by the
//! needle count fully (an added node is inside the body).
//!
//! Shape information: `rest_length`, one `f32` per slot.

use super::{
    row, BuildContext, ForceInput, ModelInfo, ModelState, ShapeArray, ShapeRow, TissueModel,
};
use crate::calibration::{calibration, UncalibratedNeighbours};
use crate::error::SceneError;
use crate::math::{gather4, sqrt4, with_w, xyz, xyz_a, Vec4};
use crate::neighbours::Neighbours;
use crate::validate::{non_negative_finite, positive_finite};
use glam::{Vec3A, Vec4 as Lanes4};

/// Parameters of the weighted mass-spring model.
#[derive(Debug, Clone, Copy, serde::Serialize, serde::Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct MassSpringParams {
    /// Spring stiffness k in N/m (scaled by the pair weight).
    pub stiffness: f64,
    /// Spring damping along the spring in N s/m (scaled by the pair weight).
    #[serde(default)]
    pub spring_damping: f64,
    /// How much of the body each spring stands for (`spring_share`, default `"cell"`).
    #[serde(default)]
    pub spring_share: SpringShare,
}

/// The share of the body a mass-spring spring stands for, a factor on its weight.
#[derive(Debug, Clone, Copy, serde::Serialize, serde::Deserialize, PartialEq, Eq, Default)]
#[serde(rename_all = "snake_case")]
pub enum SpringShare {
    /// The larger cell volume of its two nodes over an interior node's cell (`spacing^3`):
    /// 1 inside, 1/2 for a spring lying in a face of a box lattice, 1/4 along an edge: the
    /// share of the lattice cells around the spring that lie inside the body. Under a
    /// uniform strain a cube of 5^3 nodes is then 4.8% stiffer than the unbounded lattice,
    /// 9^3 nodes 0.9% (K = 18; `"equal"`: 21.5% at 9^3), and the calibration `k = C E h`
    /// barely drifts with resolution (`needlesim_core::calibration`). The price: edge and
    /// corner springs are a quarter as strong, and a cube squashed to 10% of its height
    /// and released stays 4.0% off its rest shape with K = 18 (the report's extreme
    /// cases; with K = 16 it was 19%, and 3.6% with `"equal"`).
    #[default]
    Cell,
    /// Every spring counts fully (the paper's weighted mass-spring): springs in the
    /// surface make a block stiffer than the unbounded lattice under a uniform strain, by
    /// 67% at 5^3 nodes and 8% at 25^3.
    Equal,
}

impl MassSpringParams {
    /// `model = "mass_spring"` with spring `stiffness` in N/m, the other keys at their
    /// defaults (no spring damping, `spring_share = "cell"`).
    pub const fn new(stiffness: f64) -> MassSpringParams {
        MassSpringParams {
            stiffness,
            spring_damping: 0.0,
            spring_share: SpringShare::Cell,
        }
    }

    /// `spring_damping` in N s/m.
    pub const fn with_spring_damping(mut self, spring_damping: f64) -> Self {
        self.spring_damping = spring_damping;
        self
    }

    /// `spring_share`.
    pub const fn with_spring_share(mut self, spring_share: SpringShare) -> Self {
        self.spring_share = spring_share;
        self
    }
}

impl TissueModel for MassSpringParams {
    type Shape = Shape;

    const INFO: ModelInfo = ModelInfo {
        tag: "mass_spring",
        short_name: "msm",
        label: "mass-spring",
        structural_keys: &["spring_share"],
    };

    fn validate(&self, key: &str) -> Result<(), SceneError> {
        positive_finite(&format!("{key}.stiffness"), self.stiffness)?;
        non_negative_finite(&format!("{key}.spring_damping"), self.spring_damping)
    }

    /// `[k, c, 0, 0]`.
    fn material_row(&self) -> Vec4 {
        [self.stiffness as f32, self.spring_damping as f32, 0.0, 0.0]
    }

    /// One rest length per slot.
    fn shape_bytes_per_node(&self, k: f64) -> f64 {
        4.0 * k
    }

    /// `E = k / (C h)` with the lattice's calibration constant; the lattice's Poisson
    /// ratio is about 1/4 (docs/report).
    fn elastic_moduli(
        &self,
        spacing: f64,
        neighbours: usize,
    ) -> Result<(f64, f64), UncalibratedNeighbours> {
        let cal = calibration(neighbours)?;
        Ok((self.stiffness / (cal.mass_spring * spacing), 0.25))
    }

    /// Measured on a free 13^3-node cube (the report's "What each model represents", K =
    /// 18): Poisson ratio 0.22, bulk and shear moduli 0.71 and 0.83 of those of an
    /// isotropic solid with the same E and nu = 0.3, cubic anisotropy 0.78.
    fn limitation(&self) -> Option<&'static str> {
        Some(
            "a lattice of central springs: its Poisson ratio is about 0.22 and its bulk and \
             shear stiffness are tied together, whatever the material asks (the stiffness sets \
             E through k = C E h); use a continuum model where nu matters",
        )
    }

    fn prepare_neighbours(
        &self,
        nb: &mut Neighbours,
        node_volumes: &[f64],
        spacing: f64,
        n: usize,
    ) {
        if self.spring_share == SpringShare::Cell {
            apply_cell_shares(nb, node_volumes, spacing, n);
        }
    }

    fn build(&self, rest: &[Vec4], nb: &Neighbours, n: usize, _ctx: BuildContext) -> Shape {
        Shape {
            params: *self,
            rest_length: rest_lengths(rest, nb, n),
        }
    }
}

/// The mass-spring model's shape information.
#[derive(Debug, Clone, PartialEq)]
pub struct Shape {
    /// The parameters.
    pub params: MassSpringParams,
    /// `capacity * K` rest lengths in metres.
    pub rest_length: Vec<f32>,
}

impl ModelState for Shape {
    fn arrays(&self) -> Vec<(ShapeArray, &[u8])> {
        vec![(
            ShapeArray::RestLength,
            bytemuck::cast_slice(&self.rest_length),
        )]
    }

    fn arrays_mut(&mut self) -> Vec<(ShapeArray, &mut [u8])> {
        vec![(
            ShapeArray::RestLength,
            bytemuck::cast_slice_mut(&mut self.rest_length),
        )]
    }

    fn node_rows(
        &self,
        i: usize,
        rest: &[Vec4],
        nb: &Neighbours,
        _volume_scale: f64,
        _rest_position: bool,
    ) -> Vec<ShapeRow> {
        vec![row(
            ShapeArray::RestLength,
            i,
            &rest_length_row(i, rest, nb),
        )]
    }

    fn cpu_forces(&mut self, input: &ForceInput, forces: &mut [Vec4]) {
        let ForceInput {
            positions: pos,
            velocities: vel,
            nb,
            ..
        } = *input;
        let rest_length = &self.rest_length[..];
        match input.node_material {
            None => {
                let p = &self.params;
                let (k, c) = (p.stiffness as f32, p.spring_damping as f32);
                input
                    .threads
                    .map_nodes(forces, |i| force(i, pos, vel, nb, rest_length, k, c))
            }
            Some(m) => input
                .threads
                .map_nodes(forces, |i| force_mixed(i, pos, vel, nb, rest_length, m)),
        }
    }
}

/// Multiplies the weight of every spring of the first `n` nodes by its share of the body,
/// `max(V_i, V_j) / spacing^3` ([`SpringShare::Cell`]). Both slots of a
/// mutual pair get the same bits, so the lists stay mutual.
pub fn apply_cell_shares(nb: &mut Neighbours, node_volumes: &[f64], spacing: f64, n: usize) {
    let cell = spacing.powi(3);
    let scaled: Vec<(usize, f32)> = (0..n)
        .flat_map(|i| nb.live(i).map(move |s| (i, s)))
        .map(|(i, (slot, j, w))| {
            let share = node_volumes[i].max(node_volumes[j]) / cell;
            (slot, (w as f64 * share) as f32)
        })
        .collect();
    for (slot, w) in scaled {
        nb.weight[slot] = w;
    }
}

/// Rest length per neighbour slot (`capacity * K`; 0 for empty slots).
pub fn rest_lengths(rest: &[Vec4], nb: &Neighbours, n: usize) -> Vec<f32> {
    let mut out = vec![0.0f32; nb.index.len()];
    for i in 0..n {
        out[i * nb.k..(i + 1) * nb.k].copy_from_slice(&rest_length_row(i, rest, nb));
    }
    out
}

/// The K rest lengths of node i's row (0 for empty slots).
pub fn rest_length_row(i: usize, rest: &[Vec4], nb: &Neighbours) -> Vec<f32> {
    let mut row = vec![0.0f32; nb.k];
    for (slot, j, _) in nb.live(i) {
        row[slot - i * nb.k] = (xyz(rest[j]) - xyz(rest[i])).length();
    }
    row
}

/// Elastic plus spring-damping force on node `i`, four slots at a time.
///
/// Each group of four slots gathers its neighbours' positions (and velocities when
/// `damping != 0`) and transposes them into x, y and z lanes, so the four lengths, the
/// square roots and the divisions are single SIMD instructions (`Vec4` is an SSE2 or NEON
/// register); an empty slot (weight 0) or a coincident pair is masked out rather than
/// branched over. Slots past the last group of four go through [`force_scalar`]. Every
/// slot computes what [`force_scalar`] computes; only the order of the final sum differs
/// (each lane is summed, then the lanes, then the remainder), and it is the same for
/// every node and thread count, so results stay deterministic.
#[inline]
pub fn force(
    i: usize,
    positions: &[Vec4],
    velocities: &[Vec4],
    nb: &Neighbours,
    rest_length: &[f32],
    stiffness: f32,
    damping: f32,
) -> Vec4 {
    if damping == 0.0 {
        force_lanes::<false>(
            i,
            positions,
            velocities,
            nb,
            rest_length,
            stiffness,
            damping,
        )
    } else {
        force_lanes::<true>(
            i,
            positions,
            velocities,
            nb,
            rest_length,
            stiffness,
            damping,
        )
    }
}

#[inline(always)]
fn force_lanes<const DAMPED: bool>(
    i: usize,
    positions: &[Vec4],
    velocities: &[Vec4],
    nb: &Neighbours,
    rest_length: &[f32],
    stiffness: f32,
    damping: f32,
) -> Vec4 {
    let k = nb.k;
    let row = i * k..(i + 1) * k;
    let (index, weight, rest) = (
        &nb.index[row.clone()],
        &nb.weight[row.clone()],
        &rest_length[row],
    );
    let [xx, xy, xz, _] = positions[i];
    let [vx, vy, vz, _] = velocities[i];
    let (xx, xy, xz) = (Lanes4::splat(xx), Lanes4::splat(xy), Lanes4::splat(xz));
    let (vx, vy, vz) = (Lanes4::splat(vx), Lanes4::splat(vy), Lanes4::splat(vz));
    let (k4, c4) = (Lanes4::splat(stiffness), Lanes4::splat(damping));
    let mut f = [Lanes4::ZERO; 3];
    let groups = k / 4;
    for g in 0..groups {
        let s = 4 * g;
        let j = [index[s], index[s + 1], index[s + 2], index[s + 3]].map(|j| j as usize);
        let w = Lanes4::from_slice(&weight[s..s + 4]);
        let l0 = Lanes4::from_slice(&rest[s..s + 4]);
        let p = gather4(positions, j);
        let (dx, dy, dz) = (p.x_axis - xx, p.y_axis - xy, p.z_axis - xz);
        let len = sqrt4(dx * dx + dy * dy + dz * dz);
        let inv = Lanes4::ONE / len;
        let mut t = k4 * (len - l0);
        if DAMPED {
            let v = gather4(velocities, j);
            let dv = (v.x_axis - vx) * dx + (v.y_axis - vy) * dy + (v.z_axis - vz) * dz;
            t += c4 * dv * inv;
        }
        let mag = w * t * inv;
        let live = w.cmpne(Lanes4::ZERO) & len.cmpgt(Lanes4::ZERO);
        f[0] += Lanes4::select(live, mag * dx, Lanes4::ZERO);
        f[1] += Lanes4::select(live, mag * dy, Lanes4::ZERO);
        f[2] += Lanes4::select(live, mag * dz, Lanes4::ZERO);
    }
    let sum = Vec3A::new(f[0].element_sum(), f[1].element_sum(), f[2].element_sum());
    let tail = slot_forces(
        i,
        4 * groups..k,
        positions,
        velocities,
        nb,
        rest_length,
        stiffness,
        damping,
    );
    with_w((sum + tail).into(), 0.0)
}

/// The same force one slot at a time: the reference [`force`] is checked against, and
/// what it uses for the slots past its last group of four.
#[inline]
pub fn force_scalar(
    i: usize,
    positions: &[Vec4],
    velocities: &[Vec4],
    nb: &Neighbours,
    rest_length: &[f32],
    stiffness: f32,
    damping: f32,
) -> Vec4 {
    let f = slot_forces(
        i,
        0..nb.k,
        positions,
        velocities,
        nb,
        rest_length,
        stiffness,
        damping,
    );
    with_w(f.into(), 0.0)
}

/// Series mean `2 a b / (a + b)` of two spring constants (0 when both are 0): the
/// constant of a spring whose halves lie in two materials.
#[inline(always)]
pub fn series_mean(a: f32, b: f32) -> f32 {
    let s = a + b;
    if s > 0.0 {
        2.0 * a * b / s
    } else {
        0.0
    }
}

/// The force on node `i` with a material per node (`material[j] = [k_j, c_j, _, _]`,
/// [`super::material_row`]): each spring takes the [`series_mean`] of its nodes' stiffness
/// and damping, so the pair forces stay equal and opposite.
#[inline]
pub fn force_mixed(
    i: usize,
    positions: &[Vec4],
    velocities: &[Vec4],
    nb: &Neighbours,
    rest_length: &[f32],
    material: &[Vec4],
) -> Vec4 {
    let xi = xyz_a(positions[i]);
    let vi = xyz_a(velocities[i]);
    let [ki, ci, _, _] = material[i];
    let mut f = Vec3A::ZERO;
    for slot in i * nb.k..(i + 1) * nb.k {
        let w = nb.weight[slot];
        if w == 0.0 {
            continue;
        }
        let j = nb.index[slot] as usize;
        let d = xyz_a(positions[j]) - xi;
        let len = d.length();
        if len <= 0.0 {
            continue;
        }
        let (k, c) = (
            series_mean(ki, material[j][0]),
            series_mean(ci, material[j][1]),
        );
        let inv = 1.0 / len;
        let dv = xyz_a(velocities[j]) - vi;
        let mag = w * (k * (len - rest_length[slot]) + c * dv.dot(d) * inv) * inv;
        f += mag * d;
    }
    with_w(f.into(), 0.0)
}

/// Sum of the spring forces of node `i`'s slots `slots` (0-based within its row).
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn slot_forces(
    i: usize,
    slots: std::ops::Range<usize>,
    positions: &[Vec4],
    velocities: &[Vec4],
    nb: &Neighbours,
    rest_length: &[f32],
    stiffness: f32,
    damping: f32,
) -> Vec3A {
    let xi = xyz_a(positions[i]);
    let vi = xyz_a(velocities[i]);
    let mut f = Vec3A::ZERO;
    for slot in slots.start + i * nb.k..slots.end + i * nb.k {
        let w = nb.weight[slot];
        if w == 0.0 {
            continue;
        }
        let d = xyz_a(positions[nb.index[slot] as usize]) - xi;
        let len = d.length();
        if len <= 0.0 {
            continue;
        }
        let inv = 1.0 / len;
        let dv = xyz_a(velocities[nb.index[slot] as usize]) - vi;
        let mag = w * (stiffness * (len - rest_length[slot]) + damping * dv.dot(d) * inv) * inv;
        f += mag * d;
    }
    f
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A random cloud with random neighbour rows (some empty, some coincident) for every
    /// K from 1 to 19, damped and undamped: the four-lane force matches the scalar one to
    /// f32 rounding of the sum (relative 1e-5 of the sum of the terms' magnitudes, far
    /// above the ~K * 6e-8 a reordered f32 sum can differ by).
    #[test]
    fn lanes_match_the_scalar_force() {
        let mut rnd = crate::math::test_rng(0x2545_f491_4f6c_dd1du64);
        let n = 50;
        let pos: Vec<Vec4> = (0..n).map(|_| [rnd(), rnd(), rnd(), 1.0]).collect();
        let vel: Vec<Vec4> = (0..n)
            .map(|_| [rnd() - 0.5, rnd() - 0.5, rnd() - 0.5, 0.0])
            .collect();
        for k in 1..20 {
            let mut index = vec![0u32; n * k];
            let mut weight = vec![0f32; n * k];
            for (slot, (j, w)) in index.iter_mut().zip(weight.iter_mut()).enumerate() {
                *j = (rnd() * n as f32) as u32 % n as u32;
                if slot % 7 == 3 {
                    *j = (slot / k) as u32; // coincident: no direction
                }
                *w = if rnd() < 0.2 { 0.0 } else { rnd() };
            }
            let nb = Neighbours { k, index, weight };
            let rest: Vec<f32> = (0..n * k).map(|_| 0.5 * rnd()).collect();
            for damping in [0.0, 0.3] {
                for i in 0..n {
                    let a = force(i, &pos, &vel, &nb, &rest, 100.0, damping);
                    let b = force_scalar(i, &pos, &vel, &nb, &rest, 100.0, damping);
                    // Bound on the sum of the terms' magnitudes, |dv . d| / |d| <= |dv|.
                    let scale: f32 = (i * k..(i + 1) * k)
                        .map(|slot| {
                            let j = nb.index[slot] as usize;
                            let len = (xyz(pos[j]) - xyz(pos[i])).length();
                            let dv = (xyz(vel[j]) - xyz(vel[i])).length();
                            let live = nb.weight[slot] != 0.0 && len > 0.0;
                            let term = 100.0 * (len - rest[slot]).abs() + damping * dv;
                            if live {
                                nb.weight[slot] * term
                            } else {
                                0.0
                            }
                        })
                        .sum();
                    for c in 0..3 {
                        assert!(
                            (a[c] - b[c]).abs() <= 1e-5 * scale.max(1e-6),
                            "K = {k}, node {i}, damping {damping}: {a:?} vs {b:?}"
                        );
                    }
                    assert!(a.iter().all(|x| x.is_finite()));
                }
            }
        }
    }
}

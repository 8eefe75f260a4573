//! Physical checks of the CPU tissue models (mass-spring, local shape matching in the
//! paper's per-node form and in the conservative cluster form, Debunne meshfree FEM plain
//! and co-rotated, point based animation).

mod common;
use common::*;
use needlesim::core::scene::{DebunneParams, NeoHookeanParams, PointBasedParams};
use needlesim::{Backend, Material, NodeField, Threading};

/// Largest force at rest relative to the largest force of the same cube stretched by 30%.
/// 1e-5 is the criterion; f32 round-off of the rest state is about 1e-7 relative.
const EQUILIBRIUM_TOL: f64 = 1e-5;

fn stretched_force_scale(material: Material) -> f64 {
    let scene = cube_scene(material, 639, 0.0, [1.3, 1.0, 1.0]);
    let mut b = backend(&scene, Threading::Single);
    b.compute_forces();
    let f = max_norm(&read(&mut b, NodeField::Force));
    assert!(f > 0.0);
    f
}

#[test]
fn rest_state_is_an_equilibrium() {
    for (label, material) in all_models() {
        let scale = stretched_force_scale(material);
        let scene = cube_scene(material, 639, 0.0, [1.0; 3]);
        let mut b = backend(&scene, Threading::Single);
        b.compute_forces();
        let f = max_norm(&read(&mut b, NodeField::Force));
        assert!(
            f <= EQUILIBRIUM_TOL * scale,
            "{label}: rest force {f:e} vs stretched {scale:e}"
        );
        // And it stays at rest: 100 steps move no node by more than 1e-6 of the cube size.
        b.step(100);
        let rest = rest_positions(&scene);
        let p = read(&mut b, NodeField::Position);
        let moved = (0..rest.len())
            .map(|i| {
                (0..3)
                    .map(|a| (p[i][a] as f64 - rest[i][a]).powi(2))
                    .sum::<f64>()
                    .sqrt()
            })
            .fold(0.0, f64::max);
        assert!(moved < 1e-7, "{label}: rest state drifted by {moved:e} m");
    }
}

/// Rotates the rest shape rigidly about an axis through its centroid and checks that the
/// elastic forces vanish.
#[test]
fn rigid_rotation_gives_zero_force() {
    let axes: [[f64; 3]; 2] = [[0.0, 0.0, 1.0], [0.48, 0.6, 0.64]];
    for (label, material) in MODELS {
        let scale = stretched_force_scale(material);
        for axis in axes {
            let scene = cube_scene(material, 639, 0.0, [1.0; 3]);
            let rest = rest_positions(&scene);
            let mut b = backend(&scene, Threading::Single);
            let n = rest.len();
            let c: [f64; 3] =
                std::array::from_fn(|a| rest.iter().map(|p| p[a]).sum::<f64>() / n as f64);
            let (s, co) = std::f64::consts::FRAC_PI_2.sin_cos();
            let mut p = read(&mut b, NodeField::Position);
            for i in 0..n {
                let r: [f64; 3] = std::array::from_fn(|a| rest[i][a] - c[a]);
                // Rodrigues: r cos + (k x r) sin + k (k . r)(1 - cos)
                let kxr = [
                    axis[1] * r[2] - axis[2] * r[1],
                    axis[2] * r[0] - axis[0] * r[2],
                    axis[0] * r[1] - axis[1] * r[0],
                ];
                let kr = axis[0] * r[0] + axis[1] * r[1] + axis[2] * r[2];
                for a in 0..3 {
                    p[i][a] = (c[a] + r[a] * co + kxr[a] * s + axis[a] * kr * (1.0 - co)) as f32;
                }
            }
            b.write(NodeField::Position, 0, &p).unwrap();
            // Shape matching refines its warm-started rotation by 2 iterations per call (the
            // default); a 90 degree jump from the identity takes tens of calls on flat surface
            // clusters, where the iteration converges linearly.
            for _ in 0..50 {
                b.compute_forces();
            }
            let f = max_norm(&read(&mut b, NodeField::Force));
            assert!(
                f <= EQUILIBRIUM_TOL * scale,
                "{label} axis {axis:?}: force {f:e} after rotation vs stretched {scale:e}"
            );
        }
    }
}

/// A free cube stretched by 30% along x and released comes back to its rest shape within
/// 1% of its edge, after removing the best-fit rigid motion: a deformable body with zero
/// angular momentum may still end up turned (measured: about 0.01 rad for the mass-spring
/// cube, whose lattice neighbourhoods couple stretch and shear).
#[test]
fn stretched_cube_returns_to_rest() {
    use needlesim::core::glam::{Mat3, Quat};
    use needlesim::core::models::mueller2016_rotation::extract_rotation;
    // Damping 20/s: enough for the paper's non-conservative shape matching forces at
    // k_s = 20 N/m (see local_shape_matching module docs).
    for (label, material) in all_models() {
        let scene = cube_scene(material, 639, 20.0, [1.3, 1.0, 1.0]);
        let rest = rest_positions(&scene);
        let mut b = backend(&scene, Threading::Parallel);
        b.step(4000);
        b.check_finite().unwrap();
        let p = read(&mut b, NodeField::Position);
        let n = rest.len();
        let cp: [f64; 3] =
            std::array::from_fn(|a| (0..n).map(|i| p[i][a] as f64).sum::<f64>() / n as f64);
        let cr: [f64; 3] =
            std::array::from_fn(|a| (0..n).map(|i| rest[i][a]).sum::<f64>() / n as f64);
        // Best-fit rotation: the rotation of the polar decomposition of sum (p - cp)(r - cr)^T.
        let mut m = [[0.0f32; 3]; 3];
        for i in 0..n {
            for r in 0..3 {
                for c in 0..3 {
                    m[r][c] += ((p[i][r] as f64 - cp[r]) * (rest[i][c] - cr[c])) as f32;
                }
            }
        }
        let m = Mat3::from_cols_array_2d(&m).transpose();
        let rot = Mat3::from_quat(extract_rotation(&m, Quat::IDENTITY, 500))
            .transpose()
            .to_cols_array_2d();
        let worst = (0..n)
            .map(|i| {
                let d: [f64; 3] = std::array::from_fn(|a| rest[i][a] - cr[a]);
                (0..3)
                    .map(|a| {
                        let rd: f64 = (0..3).map(|c| rot[a][c] as f64 * d[c]).sum();
                        (p[i][a] as f64 - cp[a] - rd).powi(2)
                    })
                    .sum::<f64>()
                    .sqrt()
            })
            .fold(0.0, f64::max);
        assert!(
            worst < 0.01 * 0.1,
            "{label}: max distance from rest shape {worst:e} m"
        );
        let shift: [f64; 3] = std::array::from_fn(|a| cp[a] - cr[a]);
        assert!(
            shift.iter().all(|s| s.abs() < 1e-4),
            "{label}: drifted {shift:?}"
        );
    }
}

/// Mass-spring, cluster shape matching and the two energy-based continuum models conserve
/// momentum: the forces sum to zero up to f32 summation round-off (1e-5 of the sum of
/// force magnitudes).
#[test]
fn momentum_conserving_forces_sum_to_zero() {
    for (label, material) in [MODELS[0], MODELS[2], MODELS[3], MODELS[4], LINEAR_DEB] {
        let scene = cube_scene(material, 639, 0.0, [1.3, 0.9, 1.1]);
        let mut b = backend(&scene, Threading::Single);
        // Shear it too, so the check does not rely on the stretch's symmetry.
        let mut p = read(&mut b, NodeField::Position);
        for x in p.iter_mut() {
            x[0] += 0.2 * x[1];
        }
        b.write(NodeField::Position, 0, &p).unwrap();
        b.compute_forces();
        let f = read(&mut b, NodeField::Force);
        let sum: [f64; 3] = std::array::from_fn(|a| f.iter().map(|v| v[a] as f64).sum());
        let mag: f64 = f.iter().map(|v| norm3(*v)).sum();
        let net = (sum[0] * sum[0] + sum[1] * sum[1] + sum[2] * sum[2]).sqrt();
        assert!(
            net <= 1e-5 * mag,
            "{label}: net force {net:e} vs total {mag:e}"
        );
    }
}

/// Every node's update depends only on the previous state, so one and two threads agree;
/// the issue asks for 1e-5 relative after 1000 steps.
#[test]
fn single_and_multi_threaded_agree() {
    for (label, material) in all_models() {
        let scene = cube_scene(material, 639, 5.0, [1.3, 1.0, 1.0]);
        let mut one = backend(&scene, Threading::Single);
        let mut two = backend(&scene, Threading::Threads(2));
        assert_eq!(two.threads(), 2);
        one.step(1000);
        two.step(1000);
        let (a, b) = (
            read(&mut one, NodeField::Position),
            read(&mut two, NodeField::Position),
        );
        let scale = max_norm(&a);
        for i in 0..a.len() {
            let d = norm3([a[i][0] - b[i][0], a[i][1] - b[i][1], a[i][2] - b[i][2], 0.0]);
            assert!(d <= 1e-5 * scale, "{label}: node {i} differs by {d:e}");
        }
    }
}

#[test]
fn built_neighbour_lists_are_mutual() {
    for nodes in [639, 2207] {
        let scene = cube_scene(MODELS[0].1, nodes, 0.0, [1.0; 3]);
        let t = needlesim::Tissue::from_scene(&scene).unwrap();
        t.neighbours.check_mutual(t.n_mesh).unwrap();
        let st = t.neighbours.stats(t.n_mesh);
        assert!(st.min >= 6 && st.mean > 12.0, "{st:?}");
    }
}

#[test]
fn gravity_sag_settles_with_fixed_face_unmoved() {
    let scene = needlesim::Scene::from_file("scenes/cube_sag_lshm.toml").unwrap();
    let rest = rest_positions(&scene);
    let mut b = backend(&scene, Threading::Parallel);
    b.step(3000);
    let p = read(&mut b, NodeField::Position);
    let v = read(&mut b, NodeField::Velocity);
    for i in 0..rest.len() {
        if rest[i][0] <= 0.001 {
            assert!(
                (0..3).all(|a| p[i][a] == rest[i][a] as f32),
                "fixed node {i} moved"
            );
        }
    }
    // Settled: every node slower than 1 mm/s; sagged: the free end moved down.
    assert!(max_norm(&v) < 1e-3, "still moving: {:e} m/s", max_norm(&v));
    let tip_drop = (0..rest.len())
        .filter(|&i| rest[i][0] > 0.099)
        .map(|i| rest[i][1] - p[i][1] as f64)
        .fold(f64::INFINITY, f64::min);
    assert!(tip_drop > 1e-3, "free face sagged only {tip_drop:e} m");
}

/// Diagonal of the assembled trilinear-hexahedron (Q1) FEM stiffness for the x
/// displacement of an interior node of a cubic lattice of spacing `h`, full 2x2x2 Gauss
/// integration: the eight elements around the node contribute equally by symmetry.
fn q1_diagonal(e: f64, nu: f64, h: f64) -> f64 {
    let lam = e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu));
    let mu = e / (2.0 * (1.0 + nu));
    let g = 1.0 / 3f64.sqrt();
    let mut k = 0.0;
    for a in [-g, g] {
        for b in [-g, g] {
            for c in [-g, g] {
                let (x, y, z) = ((1.0 + a) / 2.0, (1.0 + b) / 2.0, (1.0 + c) / 2.0);
                // Shape function of the corner at the origin: (1-x)(1-y)(1-z), gradient / h.
                let d = [
                    -(1.0 - y) * (1.0 - z) / h,
                    -(1.0 - x) * (1.0 - z) / h,
                    -(1.0 - x) * (1.0 - y) / h,
                ];
                let w = (h / 2.0).powi(3);
                k += w * ((lam + 2.0 * mu) * d[0] * d[0] + mu * (d[1] * d[1] + d[2] * d[2]));
            }
        }
    }
    8.0 * k
}

/// The stiffness of one interior node against its held neighbours (the force per metre of
/// a 10 um push), the quantity a needle's point loads see. A single node's push is not a
/// quadratic field, so the hourglass control resists it: Debunne meshfree's node
/// stiffens with alpha towards the diagonal of a trilinear FEM on the same lattice (an
/// independent reference). Measured (quadratic-consistent control, 2026-11-27): 0.121,
/// 0.256 and 0.671 of the FEM diagonal at alpha 0.1, 4 and 16 (the default); bounds: below
/// 20%, between 20% and 40%, between 40% and 100%. (With the first-order control it
/// replaced, alpha 4 gave 0.53: that one penalised curvature too.)
#[test]
fn a_single_node_stiffens_with_hourglass_control_towards_the_fem_diagonal() {
    let (e, nu) = (1e4, 0.45);
    let stiffness = |alpha: f64| {
        let m = Material::DebunneMeshfree(
            DebunneParams::new(e, nu)
                .with_corotated(true)
                .with_hourglass(alpha),
        );
        let scene = cube_scene(m, 343, 0.0, [1.0; 3]);
        let rest = rest_positions(&scene);
        let c = (0..rest.len())
            .min_by(|&a, &b| {
                let d = |i: usize| (0..3).map(|k| (rest[i][k] - 0.05).powi(2)).sum::<f64>();
                d(a).total_cmp(&d(b))
            })
            .unwrap();
        let mut b = backend(&scene, Threading::Single);
        let push = 1e-5f32;
        b.compute_forces();
        let f0 = read(&mut b, NodeField::Force)[c][0];
        let mut p = [read(&mut b, NodeField::Position)[c]];
        p[0][0] += push;
        b.write(NodeField::Position, c, &p).unwrap();
        b.compute_forces();
        let f1 = read(&mut b, NodeField::Force)[c][0];
        -((f1 - f0) as f64) / push as f64
    };
    let fem = q1_diagonal(e, nu, 0.1 / 6.0);
    let (soft, medium, stiff) = (
        stiffness(0.1) / fem,
        stiffness(4.0) / fem,
        stiffness(16.0) / fem,
    );
    eprintln!(
        "node stiffness / Q1 FEM diagonal: alpha 0.1 {soft:.3}, alpha 4 {medium:.3}, alpha 16 {stiff:.3}"
    );
    assert!(soft < 0.2, "{soft}");
    assert!((0.2..0.4).contains(&medium), "{medium}");
    assert!((0.4..1.0).contains(&stiff), "{stiff}");
}

/// The hourglass control penalises only the part of a neighbourhood's motion that a
/// quadratic field cannot explain (`models/mls.rs`): a quadratic displacement field
/// gets the same forces with alpha 0 and alpha 16, so bending is not stiffened by it,
/// while a zig-zag field (every other lattice node moved, a zero-energy mode of the
/// nodal gradient) gets forces that grow with alpha. Every continuum model, a 7^3
/// lattice (surface nodes included), CPU.
#[test]
fn hourglass_control_leaves_quadratic_fields_alone_and_resists_zig_zags() {
    let (e, nu) = (1e4, 0.3);
    let models = [
        Material::DebunneMeshfree(DebunneParams::new(e, nu)),
        Material::DebunneMeshfree(DebunneParams::new(e, nu).with_corotated(true)),
        Material::PointBased(PointBasedParams::new(e, nu)),
        Material::NeoHookean(NeoHookeanParams::new(e, nu)),
    ];
    let h = 0.1 / 6.0;
    for m in models {
        let label = m.tag();
        let forces = |alpha: f64, field: &dyn Fn([f64; 3]) -> [f64; 3]| {
            let m = m.clone().with_key("hourglass", alpha).unwrap();
            let scene = cube_scene(m, 343, 0.0, [1.0; 3]);
            let rest = rest_positions(&scene);
            let mut b = backend(&scene, Threading::Single);
            let p: Vec<[f32; 4]> = read(&mut b, NodeField::Position)
                .iter()
                .zip(&rest)
                .map(|(p, x)| {
                    let u = field(*x);
                    [
                        (x[0] + u[0]) as f32,
                        (x[1] + u[1]) as f32,
                        (x[2] + u[2]) as f32,
                        p[3],
                    ]
                })
                .collect();
            b.write(NodeField::Position, 0, &p).unwrap();
            b.compute_forces();
            read(&mut b, NodeField::Force)
        };
        let apart = |a: &[[f32; 4]], b: &[[f32; 4]]| {
            let d: Vec<[f32; 4]> = a
                .iter()
                .zip(b)
                .map(|(a, b)| [a[0] - b[0], a[1] - b[1], a[2] - b[2], 0.0])
                .collect();
            max_norm(&d) / max_norm(a)
        };
        // A bend, a twist-like shear and a bulge: 0.1% strains over the 10 cm cube.
        let quadratic = |x: [f64; 3]| {
            let (a, b, c) = (x[0] - 0.05, x[1] - 0.05, x[2] - 0.05);
            [
                0.1 * b * b + 0.05 * a * c,
                0.08 * a * a - 0.06 * b * c,
                0.07 * a * b + 0.04 * c * c,
            ]
        };
        let zig_zag = |x: [f64; 3]| {
            let parity: i64 = x.iter().map(|v| (v / h).round() as i64).sum();
            [if parity % 2 == 0 { 1e-5 } else { -1e-5 }, 0.0, 0.0]
        };
        let q = apart(&forces(0.0, &quadratic), &forces(16.0, &quadratic));
        let z = apart(&forces(0.0, &zig_zag), &forces(16.0, &zig_zag));
        eprintln!(
            "{label}: alpha 0 -> 16 changes the forces by {q:e} (quadratic), {z:e} (zig-zag)"
        );
        // Rounding only (measured 1.2e-4 for every model: the f32 differences of a 0.1%
        // strain field); the zig-zag's forces grow tenfold (measured 9.95).
        assert!(q < 1e-3, "{label}: a quadratic field is stiffened by {q:e}");
        assert!(z > 1.0, "{label}: a zig-zag is resisted by only {z:e}");
    }
}

/// `Backend::compute_forces_on` (the needle's settle asks for a few nodes' forces): on
/// the CPU it evaluates only those nodes and what their forces read, and must give each
/// of them exactly the force of a whole-tissue evaluation, for every model (the two-pass
/// models read their neighbours' first pass; shape matching's cluster forces their
/// neighbours' frames; viscoelastic Debunne its relaxation state).
#[test]
fn local_force_evaluation_gives_the_whole_evaluations_forces() {
    use needlesim::core::models::viscoelastic::{Prony, PronyTerm};
    let visco = Prony::new(&[PronyTerm { g: 0.3, tau: 0.05 }]);
    let mut models = all_models();
    models.push((
        "deb-corotated-visco",
        Material::DebunneMeshfree(
            DebunneParams::new(1e4, 0.3)
                .with_corotated(true)
                .with_viscoelastic(visco),
        ),
    ));
    models.push((
        "pba-visco",
        Material::PointBased(PointBasedParams::new(1e4, 0.3).with_viscoelastic(visco)),
    ));
    for (label, material) in models {
        let scene = cube_scene(material, 639, 5.0, [1.3, 1.0, 1.0]);
        let (mut whole, mut local) = (
            backend(&scene, Threading::Single),
            backend(&scene, Threading::Single),
        );
        // Some steps first, so that rotations, warm starts and relaxation state are not
        // at their initial values (the same on both).
        whole.step(30);
        local.step(30);
        let n = whole.n_active();
        // A corner, an interior node, a face node and the last one, unsorted.
        let subset = [(n - 1) as u32, 0, 333, 17, 333];
        whole.compute_forces();
        local
            .write(NodeField::Force, 0, &vec![[f32::NAN; 4]; n])
            .unwrap();
        local.compute_forces_on(&subset);
        let (a, b) = (
            read(&mut whole, NodeField::Force),
            read(&mut local, NodeField::Force),
        );
        for &i in &subset {
            let i = i as usize;
            assert!(
                max_norm(&a[i..i + 1]) > 0.0,
                "{label}: node {i} carries no force"
            );
            assert_eq!(
                a[i].map(f32::to_bits),
                b[i].map(f32::to_bits),
                "{label}: node {i}"
            );
        }
        // Nodes outside the subset are not evaluated (they keep what was written).
        assert!(b[100][0].is_nan(), "{label}: node 100 was evaluated");
    }
}

/// The linear patch test on a resampled ball (surface-net vertices over an interior
/// lattice: the node clouds whose nodal integration is not consistent,
/// `core/src/models/consistency.rs`): under a uniform strain every node's internal force
/// must balance the traction `sigma a_k` of its share `a_k` of the outward area (zero
/// inside). With the integration corrections the mismatch (RMS over the nodes, relative
/// to the traction's) must be below a tenth of what the plain gradient leaves: measured
/// 2.5% against 63% at 463 nodes on the dev machine (the solve's damping keeps a
/// remainder, module docs). The stable step must stay within 15% of the plain one's
/// (measured 12.4% shorter: 7.73e-4 against 8.82e-4 s).
#[test]
fn integration_corrections_pass_the_linear_patch_test() {
    use needlesim::core::models::consistency::{patch_test_residual, CORRECTION_OFFSET};
    use needlesim::core::models::ModelShape;
    use needlesim::core::stability::max_eigenvalue;
    use needlesim::{CpuBackend, Tissue};
    let corrected = resampled_ball(Material::debunne(1e4, 0.3));
    let mut plain = corrected.clone();
    let ModelShape::DebunneMeshfree(shape) = &mut plain.shape.model else {
        panic!("a Debunne tissue")
    };
    for row in shape.continuum.inverse_moment.iter_mut() {
        row[CORRECTION_OFFSET..].fill(0.0);
    }
    let n = corrected.n_mesh;
    let rest: Vec<[f64; 3]> = corrected.state.positions[..n]
        .iter()
        .map(|p| [p[0] as f64, p[1] as f64, p[2] as f64])
        .collect();
    // A uniform strain: u = eps G x, G symmetric with every component.
    let g = [[1.0, 0.3, -0.2], [0.3, -0.5, 0.4], [-0.2, 0.4, 0.7]];
    let eps = 1e-4;
    let (lambda, mu) = needlesim::core::models::mls::lame(1e4, 0.3);
    let tr = g[0][0] + g[1][1] + g[2][2];
    let sigma =
        |a: usize, b: usize| eps * (2.0 * mu * g[a][b] + if a == b { lambda * tr } else { 0.0 });
    let mismatch = |tissue: &Tissue| {
        let ModelShape::DebunneMeshfree(shape) = &tissue.shape.model else {
            unreachable!()
        };
        let c = &shape.continuum;
        // a_k alone: the residual of zero corrections and zero gradient weights is a_k - b_k;
        // take a_k from the surface directly.
        let mut area = vec![[0.0f64; 3]; n];
        for tri in &tissue.triangles {
            let [p, q, s] = tri.map(|v| rest[v as usize]);
            let e1 = [q[0] - p[0], q[1] - p[1], q[2] - p[2]];
            let e2 = [s[0] - p[0], s[1] - p[1], s[2] - p[2]];
            let cr = [
                e1[1] * e2[2] - e1[2] * e2[1],
                e1[2] * e2[0] - e1[0] * e2[2],
                e1[0] * e2[1] - e1[1] * e2[0],
            ];
            for v in tri {
                for a in 0..3 {
                    area[*v as usize][a] += cr[a] / 6.0;
                }
            }
        }
        let mut b = CpuBackend::new(tissue.clone(), Threading::Single).unwrap();
        let moved: Vec<_> = rest
            .iter()
            .map(|x| {
                let u: Vec<f64> = (0..3)
                    .map(|a| eps * (0..3).map(|c| g[a][c] * x[c]).sum::<f64>())
                    .collect();
                [
                    (x[0] + u[0]) as f32,
                    (x[1] + u[1]) as f32,
                    (x[2] + u[2]) as f32,
                    1.0,
                ]
            })
            .collect();
        b.write(NodeField::Position, 0, &moved).unwrap();
        b.compute_forces();
        let f = read(&mut b, NodeField::Force);
        let (mut miss, mut load) = (0.0f64, 0.0f64);
        for (fk, ak) in f.iter().zip(&area) {
            for (a, fa) in fk.iter().take(3).enumerate() {
                let t: f64 = (0..3).map(|c| sigma(a, c) * ak[c]).sum();
                miss += (*fa as f64 + t).powi(2);
                load += t * t;
            }
        }
        // The same defect in the constraint itself (geometry only, no forces).
        let r = patch_test_residual(
            &c.rest_position,
            &tissue.neighbours,
            n,
            &tissue.triangles,
            &c.inverse_moment,
        );
        let residual = r.iter().map(|v| v.length_squared()).sum::<f64>().sqrt();
        ((miss / load).sqrt(), residual)
    };
    let ((before, residual_before), (after, residual_after)) =
        (mismatch(&plain), mismatch(&corrected));
    // Measured 1.16e-3 and 4.7e-5 m^2.
    assert!(
        residual_after < 0.1 * residual_before,
        "constraint residual {residual_after:e} with the corrections, {residual_before:e} without"
    );
    assert!(
        after < 0.1 * before,
        "force mismatch of the uniform strain: {after:.4} with the corrections, {before:.4} without"
    );
    let dt = |t: &Tissue| {
        let mut b = CpuBackend::new(t.clone(), Threading::Single).unwrap();
        max_eigenvalue(&mut b, 40).unwrap().critical_dt
    };
    let (dt_plain, dt_corrected) = (dt(&plain), dt(&corrected));
    assert!(
        dt_corrected > 0.85 * dt_plain,
        "critical step {dt_corrected:e} with the corrections, {dt_plain:e} without"
    );
    eprintln!(
        "mismatch {before:.4} -> {after:.4}, critical dt {dt_plain:.4e} -> {dt_corrected:.4e}"
    );
}

/// With the integration corrections, where they are large (the resampled ball): a rigid
/// rotation by 90 degrees about an oblique axis gives no force for the rotation-invariant
/// continuum models (the correction is blind to fields linear in the rest offsets), to
/// the cube test's tolerance against the same ball stretched by 30%; and Debunne's
/// stiffness is symmetric (its forces are the gradient of one energy): central
/// differences of the force of node `q` in the position of node `p` against those of `p`
/// in `q`, over pairs of neighbours, agree within 1% of the larger (f32 forces).
#[test]
fn integration_corrections_keep_rigid_motions_and_a_symmetric_stiffness() {
    use needlesim::CpuBackend;
    let axis = [0.48f64, 0.6, 0.64];
    for (label, material) in [
        (
            "deb-corotated",
            Material::DebunneMeshfree(DebunneParams::new(1e4, 0.3).with_corotated(true)),
        ),
        ("pba", Material::PointBased(PointBasedParams::new(1e4, 0.3))),
        ("nh", Material::NeoHookean(NeoHookeanParams::new(1e4, 0.3))),
    ] {
        let tissue = resampled_ball(material);
        let n = tissue.n_mesh;
        let mut b = CpuBackend::new(tissue, Threading::Single).unwrap();
        let rest = read(&mut b, NodeField::Position);
        let stretched: Vec<[f32; 4]> = rest
            .iter()
            .map(|p| [1.3 * p[0], p[1], p[2], p[3]])
            .collect();
        b.write(NodeField::Position, 0, &stretched).unwrap();
        b.compute_forces();
        let scale = max_norm(&read(&mut b, NodeField::Force));
        let (s, c) = std::f64::consts::FRAC_PI_2.sin_cos();
        let rotated: Vec<[f32; 4]> = rest
            .iter()
            .map(|p| {
                let r = [p[0] as f64, p[1] as f64 + 0.05, p[2] as f64];
                let kxr = [
                    axis[1] * r[2] - axis[2] * r[1],
                    axis[2] * r[0] - axis[0] * r[2],
                    axis[0] * r[1] - axis[1] * r[0],
                ];
                let kr = axis[0] * r[0] + axis[1] * r[1] + axis[2] * r[2];
                let q: [f64; 3] =
                    std::array::from_fn(|a| r[a] * c + kxr[a] * s + axis[a] * kr * (1.0 - c));
                [q[0] as f32, q[1] as f32, q[2] as f32, p[3]]
            })
            .collect();
        b.write(NodeField::Position, 0, &rotated).unwrap();
        for _ in 0..50 {
            b.compute_forces();
        }
        let f = max_norm(&read(&mut b, NodeField::Force)[..n]);
        eprintln!("{label}: force {f:e} after a rigid rotation vs stretched {scale:e}");
        assert!(
            f <= EQUILIBRIUM_TOL * scale,
            "{label}: force {f:e} after a rigid rotation vs stretched {scale:e}"
        );
    }
    let tissue = resampled_ball(Material::debunne(1e4, 0.3));
    let pairs: Vec<(usize, usize)> = (0..tissue.n_mesh)
        .step_by(23)
        .filter_map(|p| tissue.neighbours.live(p).nth(3).map(|(_, q, _)| (p, q)))
        .collect();
    let mut b = CpuBackend::new(tissue, Threading::Single).unwrap();
    let rest = read(&mut b, NodeField::Position);
    let delta = 2e-6f32;
    let mut force_of = |node: usize, axis: usize, d: f32| {
        let mut p = rest.clone();
        p[node][axis] += d;
        b.write(NodeField::Position, 0, &p).unwrap();
        b.compute_forces();
        read(&mut b, NodeField::Force)
    };
    let (mut checked, mut worst) = (0, 0.0f64);
    for &(p, q) in &pairs {
        for a in 0..3 {
            for c in 0..3 {
                let (plus, minus) = (force_of(p, a, delta), force_of(p, a, -delta));
                let k_qp = (plus[q][c] - minus[q][c]) as f64 / (2.0 * delta as f64);
                let (plus, minus) = (force_of(q, c, delta), force_of(q, c, -delta));
                let k_pq = (plus[p][a] - minus[p][a]) as f64 / (2.0 * delta as f64);
                let larger = k_qp.abs().max(k_pq.abs());
                if larger > 1.0 {
                    worst = worst.max((k_qp - k_pq).abs() / larger);
                    checked += 1;
                }
            }
        }
    }
    eprintln!("stiffness symmetric to {worst:e} over {checked} entries");
    assert!(
        checked > 50,
        "only {checked} stiffness entries large enough to compare"
    );
    assert!(
        worst < 0.01,
        "stiffness asymmetry {worst:e} over {checked} entries"
    );
}

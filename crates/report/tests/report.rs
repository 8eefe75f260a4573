//! The accuracy report's physics at test sizes: the continuum models against linear
//! elasticity, the calibration rule of the two models without E, every converging model's
//! error falling with resolution, and every extreme case ending stable, degraded or with a typed divergence
//! error (never a panic, never another error).

use needlesim::core::scene::BackendChoice;
use needlesim_report::cases::{run_case, CaseId, ModelId, RunSpec};
use needlesim_report::extreme::{run_extreme, ExtremeCase, ExtremeSize, Outcome};

fn spec(level: usize) -> RunSpec {
    RunSpec {
        level,
        dt_fraction: 0.5,
        backend: BackendChoice::CpuParallel,
    }
}

/// DEB, co-rotated DEB and PBA at 2197 nodes (the finest stretch tested here): the
/// end-plate stress is within 15% of E eps (PBA: of the St Venant-Kirchhoff stress, 0.3%
/// above at the 0.2% stretch) and the lateral strain within 15% of -nu eps (the issue's
/// tolerance). Measured (dev machine, K = 18): stress error 0.05% DEB and PBA; lateral
/// strain 0.03%. With the density-estimated volumes of Mueller 2004 PBA's stress error
/// was 9.0%.
#[test]
fn continuum_models_carry_e_eps_in_the_stretch() {
    for model in [
        ModelId::Deb,
        ModelId::DebCorotated,
        ModelId::Pba,
        ModelId::NeoHookean,
    ] {
        let r = run_case(CaseId::Stretch, model, &spec(2)).unwrap();
        assert!(r.converged, "{}: not settled", model.label());
        assert!(
            r.error < 0.15,
            "{}: stress error {:.3}",
            model.label(),
            r.error
        );
        assert!(
            r.secondary < 0.15,
            "{}: lateral strain error {:.3}",
            model.label(),
            r.secondary
        );
    }
}

/// Every model variant but the paper's per-node shape matching forces.
const CONVERGING: [ModelId; 6] = [
    ModelId::Msm,
    ModelId::LshmCluster,
    ModelId::Deb,
    ModelId::DebCorotated,
    ModelId::Pba,
    ModelId::NeoHookean,
];

/// `case` for `model` at the three coarsest levels; every run must settle.
fn three_levels(case: CaseId, model: ModelId) -> Vec<needlesim_report::cases::CaseResult> {
    let r: Vec<_> = (0..3)
        .map(|level| run_case(case, model, &spec(level)).unwrap())
        .collect();
    assert!(
        r.iter().all(|r| r.converged),
        "{} / {}: a run did not settle",
        case.label(),
        model.label()
    );
    r
}

/// The models that converge to linear elasticity (all but the paper's per-node shape
/// matching forces, see below): the cantilever tip error falls over 189, 496 and 1025
/// nodes ([`CaseId::error_falls`]), and DEB, co-rotated DEB and PBA are within 15% of
/// Timoshenko at 1025 nodes (the tolerance). Measured (dev machine, K = 18): msm
/// 37.1%, 20.8%, 12.7%; lshm-cluster 79.5%, 65.5%, 55.2%; DEB and PBA 25.2%, 4.0%, 2.2%
/// (the 189-node beam has 3 nodes across; without hourglass control PBA 31.9%, 5.5%,
/// 3.1%). With K = 16 mass-spring's
/// beam was anisotropic and its error stopped falling (8.5% at 1025 nodes, 11.9% at
/// 12,221).
#[test]
fn cantilever_error_falls_with_resolution() {
    for model in CONVERGING {
        let r = three_levels(CaseId::Cantilever, model);
        let e: Vec<f64> = r.iter().map(|r| r.error).collect();
        let msg = format!("{}: tip errors {e:.4?}", model.label());
        eprintln!("{msg}");
        assert!(CaseId::Cantilever.error_falls(&e), "{msg}");
        if !matches!(model, ModelId::Msm | ModelId::LshmCluster) {
            assert!(e[2] < 0.15, "{msg}");
        }
    }
}

/// The calibration rule `k = C E h` with the bulk C for K = 18
/// (`needlesim_core::calibration`): in the stretch case the error of each lattice model
/// falls with resolution (125, 729, 2197 nodes; measured on the dev machine: msm 9.2%,
/// 2.5%, 1.3%; lshm-cluster 47.0%, 18.3%, 11.0%; lshm-node 98.8%, 39.8%, 24.8%, all too
/// stiff) and the stress converges: it changes less from 729 to 2197 nodes than from 125
/// to 729, by more than the factor 2 of a first-order method (h: 25, 12.5, 8.3 mm). Bounds
/// at 2197 nodes, 1.3 to 1.6 times the measured: 2% msm (springs count by their share of
/// the body), 15% and 33% for the shape matching variants, whose surface clusters have no
/// such rule.
#[test]
fn lattice_models_converge_to_the_calibrated_modulus() {
    for (model, bound) in [
        (ModelId::Msm, 0.02),
        (ModelId::LshmCluster, 0.15),
        (ModelId::LshmNode, 0.33),
    ] {
        let r: Vec<_> = (0..3)
            .map(|level| run_case(CaseId::Stretch, model, &spec(level)).unwrap())
            .collect();
        let msg = format!(
            "{}: stress {:.2}, {:.2}, {:.2} Pa (errors {:.3}, {:.3}, {:.3})",
            model.label(),
            r[0].measured,
            r[1].measured,
            r[2].measured,
            r[0].error,
            r[1].error,
            r[2].error
        );
        eprintln!("{msg}");
        assert!(r.iter().all(|x| x.converged), "{msg}");
        assert!(r[0].error > r[1].error && r[1].error > r[2].error, "{msg}");
        assert!(r[2].error < bound, "{msg}");
        let (d1, d2) = (
            (r[1].measured - r[0].measured).abs(),
            (r[2].measured - r[1].measured).abs(),
        );
        assert!(d1 > 2.0 * d2, "{msg}");
    }
}

/// Indentation against scikit-fem over 125, 729 and 2197 nodes: the punch force error and
/// the displacement-field error fall for every model that converges to linear elasticity.
/// Measured (dev machine, K = 18, 0.1 mm punch), force: msm 21.5%, 9.3%, 4.6%;
/// lshm-cluster 55.9%, 21.8%, 13.9%; DEB 15.8%, 6.2%, 3.7%; co-rotated DEB 15.8%, 6.2%,
/// 3.7%; PBA 15.6%, 6.0%, 3.5%. With K = 16 and a 2 mm punch the lattice models' error
/// rose after 729 nodes (anisotropy) and PBA's after 729 (its Green strain at 2% nominal
/// strain is not the linear reference). Finer, mass-spring's field error levels off at
/// about 2.6% and cluster shape matching's at 7.8% (their Poisson ratios; the report).
///
/// The paper's per-node shape matching forces are not in the list: they are not the
/// gradient of an energy, their Poisson ratio is outside [0, 0.5] and their punch force
/// error does not fall (194%, 159%, 154%, 157%, 160%, 163% from 125 to 15,625 nodes); the
/// report shows them, `forces = "cluster"` is the variant that converges.
#[test]
fn indentation_error_falls_with_resolution() {
    for model in CONVERGING {
        let r = three_levels(CaseId::Indentation, model);
        let force: Vec<f64> = r.iter().map(|r| r.error).collect();
        let field: Vec<f64> = r.iter().map(|r| r.secondary).collect();
        let msg = format!(
            "{}: force errors {force:.4?}, field errors {field:.4?}",
            model.label()
        );
        eprintln!("{msg}");
        assert!(CaseId::Indentation.error_falls(&force), "{msg}");
        assert!(CaseId::Indentation.error_falls(&field), "{msg}");
    }
}

/// A curved body that is not a box lattice: a free ball (a resampled sphere) under a
/// uniform pressure, against Lame's uniform strain `-p (1 - 2 nu) / E`. For the continuum
/// models (DEB, co-rotated DEB, PBA) the strain error falls over 4, 8 and 12 spacings per
/// radius (or stays within the settle tolerance) and is within 5% at the second, 2,955
/// nodes (about 3,000), and the displacement field's RMS deviation from `eps x` (over
/// `|eps| R`) within 7%. Measured with the default hourglass control (Debunne,
/// 2026-11-27): strain 6.8%, 2.1%, 1.5%, field 17.6%, 6.1%, 3.5%. The field's error is
/// the irregular surface nodes' soft modes (4.1% at 2,955 nodes with alpha 32, 2.8% with
/// 64, at a smaller stable step and a stiffer punch; the report set the first-order
/// control to 4 for this case before, field 4.5%): `docs/guide/accuracy.md`, "Hourglass
/// control".
#[test]
fn ball_under_pressure_matches_lame_within_5_percent_at_3000_nodes() {
    for model in [ModelId::Deb, ModelId::DebCorotated, ModelId::Pba] {
        let r = three_levels(CaseId::Sphere, model);
        let strain: Vec<f64> = r.iter().map(|r| r.error).collect();
        let field: Vec<f64> = r.iter().map(|r| r.secondary).collect();
        let nodes: Vec<usize> = r.iter().map(|r| r.nodes).collect();
        let msg = format!(
            "{}: nodes {nodes:?}, strain errors {strain:.4?}, field errors {field:.4?}",
            model.label()
        );
        eprintln!("{msg}");
        assert!((2000..4500).contains(&nodes[1]), "{msg}");
        assert!(CaseId::Sphere.error_falls(&strain), "{msg}");
        assert!(strain[1] < 0.05 && field[1] < 0.07, "{msg}");
    }
}

/// A clamped curved body against an established FEM library: a standing cylinder
/// (R 2.5 cm, H 10 cm, resampled from a triangulated surface) with its bottom face fixed,
/// sagging under its weight, against scikit-fem's converged axisymmetric P2 solution
/// (`reference/column_fem.md`, itself within 0.08% of a 3D P2 solution on a gmsh mesh).
/// Every model runs at 575, 1,163 and 2,255 nodes (3, 4 and 5 spacings per radius).
/// The continuum models' mean-sag error falls and is within 5% at 2,255 nodes (the
/// issue's "about 3k"), and so is the field's RMS error over the top sag. Measured (dev
/// machine, the default hourglass control, 2026-11-27): DEB 7.54%, 5.42%, 4.54% (field
/// 5.4%, 3.8%, 3.1%), co-rotated DEB the same within 0.01%, PBA 7.80%, 5.67%, 4.79%,
/// neo-Hookean 7.42%, 5.30%, 4.43%; DEB 3.5% at 3,551 nodes (report_case). With the
/// first-order control at 4, which the report set for this case before: DEB 5.95%, 4.22%,
/// 3.73%, and 2.9% at 3,551, 2.2% at 7,851, 1.7% at 15,323 nodes. The lattice-calibrated models are bounded at 2,255 nodes
/// at about 1.5 times their measured error, not required to fall: msm 19.6%, 15.5%, 17.6%
/// (8.9% at 15,323), lshm-cluster 16.3%, 7.8%, 5.1%, lshm-node 23.2%, 10.5%, 6.8%.
#[test]
fn clamped_cylinder_sag_matches_scikit_fem() {
    for model in ModelId::ALL {
        let r = three_levels(CaseId::Column, model);
        let sag: Vec<f64> = r.iter().map(|r| r.error).collect();
        let field: Vec<f64> = r.iter().map(|r| r.secondary).collect();
        let nodes: Vec<usize> = r.iter().map(|r| r.nodes).collect();
        let msg = format!(
            "{}: nodes {nodes:?}, sag errors {sag:.4?}, field errors {field:.4?}",
            model.label()
        );
        eprintln!("{msg}");
        assert!((2000..3500).contains(&nodes[2]), "{msg}");
        match model {
            ModelId::Deb | ModelId::DebCorotated | ModelId::Pba | ModelId::NeoHookean => {
                assert!(CaseId::Column.error_falls(&sag), "{msg}");
                assert!(CaseId::Column.error_falls(&field), "{msg}");
                assert!(sag[2] < 0.05 && field[2] < 0.05, "{msg}");
            }
            ModelId::Msm => assert!(sag[2] < 0.27, "{msg}"),
            ModelId::LshmCluster => assert!(sag[2] < 0.08, "{msg}"),
            ModelId::LshmNode => assert!(sag[2] < 0.10, "{msg}"),
        }
    }
}

/// The first bending period of the clamped 0.2 x 0.02 x 0.02 m bar, from the time series
/// of its free vibration, against the lowest eigenvalue of the 3D problem from scikit-fem
/// (quadratic tetrahedra, `reference/beam_modes_fem.md`: 3.9285 s, extrapolated within
/// 3e-4): the continuum models within 2% at 2,989 nodes (the "about 3,000").
/// Measured (dev machine, dt at 0.5 of the critical step as here): DEB 0.55%, co-rotated
/// DEB 0.48%, PBA 0.55%, neo-Hookean 0.55% (periods short: the meshfree bar is stiffer);
/// at 0.3 of it 0.51%, 0.46%, 0.51%, 0.52%. Finer, the error grows to 1.0% at 6,561 and
/// 12,221 nodes (`report_case frequency <model> 5 0.3`), so it is not asserted to fall.
#[test]
fn first_bending_period_matches_the_fem_eigenvalue_at_3000_nodes() {
    for model in [
        ModelId::Deb,
        ModelId::DebCorotated,
        ModelId::Pba,
        ModelId::NeoHookean,
    ] {
        let r = run_case(CaseId::Frequency, model, &spec(3)).unwrap();
        let msg = format!(
            "{}: {} nodes, period {:.4} s against {:.4} s: error {:.4}, vs Euler-Bernoulli {:.4}",
            model.label(),
            r.nodes,
            r.measured,
            r.reference,
            r.error,
            r.secondary
        );
        eprintln!("{msg}");
        assert!(r.converged && (2500..3500).contains(&r.nodes), "{msg}");
        assert!(r.error < 0.02, "{msg}");
    }
}

/// The convergence rule of the report: falling, or within the reference's accuracy.
#[test]
fn error_falls_rule() {
    let c = CaseId::Indentation;
    assert!(c.error_falls(&[0.2, 0.1, 0.05]));
    assert!(!c.error_falls(&[0.2, 0.1, 0.12]));
    assert!(c.error_falls(&[0.2, 0.004, 0.006]));
    assert!(!c.error_falls(&[0.2, 0.004, 0.02]));
    assert!(!c.error_falls(&[0.2, f64::NAN]));
}

/// Every extreme case for every model ends stable, degraded or stopped by the divergence
/// guard with a typed error; none panics or fails otherwise. The stiff case at dt = auto
/// stays bounded for every model, and a step 10 times the automatic one is caught.
#[test]
fn extreme_cases_end_bounded_or_with_a_divergence_error() {
    let size = ExtremeSize {
        cube_side: 5,
        needle_spacing: 0.05,
        cycles: 3,
    };
    for case in ExtremeCase::ALL {
        for model in ModelId::ALL {
            let r = run_extreme(case, model, &size).unwrap();
            eprintln!(
                "{:<32} {:<14} {:?} {}",
                case.label(),
                model.label(),
                r.outcome,
                r.detail
            );
            assert!(
                !matches!(r.outcome, Outcome::Failed(_)),
                "{} / {}: {:?}",
                case.label(),
                model.label(),
                r.outcome
            );
            if case == ExtremeCase::Stiff1000Auto {
                assert!(
                    !matches!(r.outcome, Outcome::Diverged(_)),
                    "{}: {:?}",
                    model.label(),
                    r.outcome
                );
            }
            if case == ExtremeCase::Dt10x || case == ExtremeCase::Stiff1000 {
                assert!(
                    matches!(r.outcome, Outcome::Diverged(_)),
                    "{}: {:?}",
                    model.label(),
                    r.outcome
                );
            }
        }
    }
}

/// What each model represents (`needlesim_report::effective`, 9^3 nodes): the continuum
/// models have the E and nu they are given (the virial of an affine strain is exact for
/// them: within 1%), mass-spring's Poisson ratio is near 1/4 whatever is asked (0.3
/// here), cluster shape matching's near 0. Measured (dev machine): see `needlesim report`.
#[test]
fn effective_constants_say_what_each_model_represents() {
    use needlesim_report::cases::{POISSON, YOUNG};
    use needlesim_report::effective::effective;
    for model in [ModelId::Deb, ModelId::DebCorotated, ModelId::Pba] {
        let r = effective(model, 9).unwrap();
        eprintln!(
            "{}: E {:.1} Pa, nu {:.4}, A {:.4}",
            model.label(),
            r.young,
            r.poisson,
            r.anisotropy
        );
        assert!(
            (r.young / YOUNG - 1.0).abs() < 0.01,
            "{}: E {}",
            model.label(),
            r.young
        );
        assert!(
            (r.poisson / POISSON - 1.0).abs() < 0.01,
            "{}: nu {}",
            model.label(),
            r.poisson
        );
        assert!(
            (r.anisotropy - 1.0).abs() < 0.01,
            "{}: A {}",
            model.label(),
            r.anisotropy
        );
    }
    let msm = effective(ModelId::Msm, 9).unwrap();
    eprintln!(
        "msm: E {:.1} Pa, nu {:.4}, A {:.4}",
        msm.young, msm.poisson, msm.anisotropy
    );
    assert!((0.18..0.3).contains(&msm.poisson), "msm nu {}", msm.poisson);
    let lshm = effective(ModelId::LshmCluster, 9).unwrap();
    eprintln!(
        "lshm-cluster: E {:.1} Pa, nu {:.4}, A {:.4}",
        lshm.young, lshm.poisson, lshm.anisotropy
    );
    assert!(
        lshm.poisson.abs() < 0.05,
        "lshm-cluster nu {}",
        lshm.poisson
    );
    for r in needlesim_report::effective::run(13).unwrap() {
        eprintln!(
            "13^3 {}: E {:.1} Pa, nu {:.4}, K {:.1} Pa, G {:.1} Pa, A {:.4}",
            r.model.label(),
            r.young,
            r.poisson,
            r.bulk,
            r.shear,
            r.anisotropy
        );
        assert!(
            r.young.is_finite() && r.poisson.is_finite(),
            "{}",
            r.model.label()
        );
    }
}

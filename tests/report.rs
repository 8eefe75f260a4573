//! The accuracy report's physics at test sizes: the continuum models against linear
//! elasticity, the calibration rule of the two models without E, the continuum models'
//! error falling with resolution, and every extreme case ending stable, degraded or with a typed divergence
//! error (never a panic, never another error).

use needlesim::core::scene::BackendChoice;
use needlesim::report::cases::{run_case, CaseId, ModelId, RunSpec};
use needlesim::report::extreme::{run_extreme, ExtremeCase, ExtremeSize, Outcome};

fn spec(level: usize) -> RunSpec {
    RunSpec {
        level,
        dt_fraction: 0.5,
        backend: BackendChoice::CpuParallel,
    }
}

/// DEB and PBA at 2197 nodes (the finest stretch tested here): the end-plate stress is
/// E eps within 15% and the lateral strain -nu eps within 15% (the tolerance).
/// Measured (dev machine, full report): stress error 0.07% DEB, 1.4% PBA (its Green strain
/// at 1% stretch: St Venant-Kirchhoff stress is E (eps + 3/2 eps^2), 1.5% above E eps);
/// lateral strain 0.07% DEB, 0.7% PBA. With the density-estimated volumes of Mueller 2004
/// PBA's stress error was 9.0%.
#[test]
fn continuum_models_carry_e_eps_in_the_stretch() {
    for model in [ModelId::Deb, ModelId::DebCorotated, ModelId::Pba] {
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

/// DEB, co-rotated DEB and PBA cantilever tip deflection under gravity within 15% of
/// Timoshenko at 1025 nodes (the tolerance; the finest beam tested here). Measured
/// (dev machine, full report): DEB 4.2% at 496 and 3.2% at 1025 nodes, PBA 3.1% and 2.5%.
/// With uniform node volumes DEB was 26.7% off at 1025 nodes, with density volumes PBA
/// 37.8%: surface nodes weighted like interior ones make the beam too stiff in bending.
#[test]
fn continuum_cantilever_tip_within_15_percent() {
    for model in [ModelId::Deb, ModelId::DebCorotated, ModelId::Pba] {
        let r = run_case(CaseId::Cantilever, model, &spec(2)).unwrap();
        assert!(r.converged, "{}: not settled", model.label());
        assert!(
            r.error < 0.15,
            "{}: tip deflection error {:.3} at {} nodes",
            model.label(),
            r.error,
            r.nodes
        );
    }
}

/// The calibration rule `k = C E h` with the bulk C (`needlesim_core::calibration`): in
/// the stretch case the error of each lattice model falls with resolution (125, 729, 2197
/// nodes; measured on the dev machine: msm 9.4%, 4.2%, 2.7%; lshm-cluster 36.9%, 15.2%,
/// 9.4%; lshm-node 86.9%, 36.6%, 23.0%, all too stiff) and the stress converges: it changes
/// less from 729 to 2197 nodes than from 125 to 729, by more than the factor 2 of a
/// first-order method (h: 25, 12.5, 8.3 mm). Bounds at 2197 nodes: 4% msm (springs count
/// by their share of the body), 12% and 30% for the shape matching variants, whose surface
/// clusters have no such rule.
#[test]
fn lattice_models_converge_to_the_calibrated_modulus() {
    for (model, bound) in [
        (ModelId::Msm, 0.04),
        (ModelId::LshmCluster, 0.12),
        (ModelId::LshmNode, 0.3),
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

/// The continuum models converge: from 729 to 2197 nodes the displacement-field error
/// (against scikit-fem) falls for all three, and the punch force error for the two linear
/// ones. Measured (dev machine, full report): DEB force 6.5% -> 4.0% -> 2.9%, field 3.5% ->
/// 2.0% -> 1.3% at 729, 2197, 4913 nodes; co-rotated DEB force 5.6% -> 3.0% -> 1.8%. PBA's
/// Green strain is geometrically nonlinear, and at the 2 mm punch (2% nominal strain) its
/// force falls below the linear reference as the discretisation error shrinks (1.1%, 1.3%,
/// 2.4% off; field 5.6% -> 3.9% -> 3.1%). So PBA's force is held to 5% instead of a
/// falling error. Mass-spring and shape matching converge to their own material (Poisson
/// ratio about 0.24 and 0, lattice anisotropy with K = 16): their punch force error passes
/// its minimum near 729 nodes and grows towards that material's error (msm 0.9% -> 8.9%
/// from 729 to 4913 nodes), which the report shows; their convergence to the calibrated
/// modulus is tested above.
#[test]
fn continuum_error_falls_with_resolution() {
    for model in [ModelId::Deb, ModelId::DebCorotated, ModelId::Pba] {
        let a = run_case(CaseId::Indentation, model, &spec(1)).unwrap();
        let b = run_case(CaseId::Indentation, model, &spec(2)).unwrap();
        let msg = format!(
            "{}: force error {:.3} -> {:.3}, field {:.3} -> {:.3}",
            model.label(),
            a.error,
            b.error,
            a.secondary,
            b.secondary
        );
        eprintln!("{msg}");
        assert!(b.secondary < a.secondary, "{msg}");
        if model == ModelId::Pba {
            assert!(a.error < 0.05 && b.error < 0.05, "{msg}");
        } else {
            assert!(b.error < a.error, "{msg}");
        }
    }
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

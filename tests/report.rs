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
/// Measured (dev machine): stress error 3.7% DEB, 9.0% PBA, falling with resolution
/// (PBA 16.9%, 13.8%, 9.0%, 6.1% at 125, 729, 2197, 4913 nodes; lateral strain 14%, 9.5%,
/// 6.1%, 4.2%).
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

/// The calibration rule `k = C E h` reproduces E in the case it was calibrated on
/// (2197 nodes) within 1% (the constants are rounded to 4 digits; the relaxation stops at
/// 1e-3), and is off by less than 30% at 729 nodes (the rule's resolution dependence,
/// measured +11% to +17%, reported).
#[test]
fn calibration_rule_reproduces_young_modulus() {
    for model in [ModelId::Msm, ModelId::LshmNode, ModelId::LshmCluster] {
        let r = run_case(CaseId::Stretch, model, &spec(2)).unwrap();
        assert!(
            r.error < 0.01,
            "{}: stress error {:.4}",
            model.label(),
            r.error
        );
        let coarse = run_case(CaseId::Stretch, model, &spec(1)).unwrap();
        assert!(
            coarse.error < 0.3,
            "{}: stress error {:.3} at {} nodes",
            model.label(),
            coarse.error,
            coarse.nodes
        );
    }
}

/// The continuum models converge: from 729 to 2197 nodes both the punch force error
/// (against scikit-fem) and the displacement-field error fall. Measured (dev machine,
/// release): DEB force 12.9% -> 8.5% -> 6.5% and field 6.9% -> 3.9% -> 2.7% at 729,
/// 2197, 4913 nodes; PBA force 39.8% -> 27.7% -> 21.2%, field 12.2% -> 7.7% -> 5.8%.
/// Mass-spring and shape matching do not converge to the continuum (their calibrated
/// effective modulus drifts with resolution, calibration module): their force error
/// grows from 729 to 4913 nodes (msm 13% -> 25%), which the report shows.
#[test]
fn continuum_error_falls_with_resolution() {
    for model in [ModelId::Deb, ModelId::DebCorotated, ModelId::Pba] {
        let a = run_case(CaseId::Indentation, model, &spec(1)).unwrap();
        let b = run_case(CaseId::Indentation, model, &spec(2)).unwrap();
        eprintln!(
            "{}: force error {:.3} -> {:.3}, field {:.3} -> {:.3}",
            model.label(),
            a.error,
            b.error,
            a.secondary,
            b.secondary
        );
        assert!(
            b.error < a.error && b.secondary < a.secondary,
            "{}: force error {:.3} -> {:.3}, field {:.3} -> {:.3}",
            model.label(),
            a.error,
            b.error,
            a.secondary,
            b.secondary
        );
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

//! A 22 G steel needle as a cantilever (issue 43's first step): its tip deflection under a
//! lateral tip force, from the linear range to large deflection, against Euler-Bernoulli.
//!
//!     cargo run --release --example flexible_needle [SEGMENTS]
use needlesim::needle::rod::{solve, DQuat, DVec3, Loads, PointLoad, ShaftSpec};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let segments = std::env::args()
        .nth(1)
        .map_or(Ok(20), |s| s.parse::<usize>())?;
    // 10 cm of 22 G regular-wall tubing: 0.718 mm outer, 0.413 mm inner diameter.
    let spec = ShaftSpec::steel(0.1, 0.718e-3, 0.413e-3, segments);
    spec.validate()?;
    let ei = spec.bending_stiffness();
    println!(
        "22 G steel needle, {} mm, {segments} elements: EI = {:.4e} N m^2, GJ = {:.4e} N m^2",
        spec.length * 1e3,
        ei,
        spec.torsional_stiffness()
    );
    println!("tip force N | tip deflection mm | Euler-Bernoulli mm | ratio | iterations");
    for p in [1e-3, 1e-2, 0.05, 0.1, 0.2] {
        let loads = Loads {
            points: vec![PointLoad {
                s: spec.length,
                force: DVec3::X * p,
                moment: DVec3::ZERO,
            }],
            per_length: DVec3::ZERO,
        };
        let shape = solve(&spec, DVec3::ZERO, DQuat::IDENTITY, &loads)?;
        let linear = p * spec.length.powi(3) / (3.0 * ei);
        println!(
            "{p:>11.3} | {:>17.4} | {:>18.4} | {:.4} | {}",
            shape.tip().x * 1e3,
            linear * 1e3,
            shape.tip().x / linear,
            shape.iterations
        );
    }
    Ok(())
}

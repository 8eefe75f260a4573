//! Prints the needle force trace of a needle scene every `every` steps.
use needlesim::needle::Simulation;
use needlesim::{CpuBackend, Scene, Threading};
fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let scene = Scene::from_file(
        args.get(1)
            .map_or("scenes/needle_insert_extract.toml", |s| s),
    )?;
    let every: u64 = args.get(2).map_or(100, |s| s.parse().unwrap());
    let prep = Simulation::prepare(&scene)?;
    let backend = CpuBackend::new(prep.tissue.clone(), Threading::Single)?;
    let mut sim = prep.start(Box::new(backend))?;
    for _ in 0..scene.run.steps {
        sim.step()?;
        if sim.steps() % every == 0 {
            let s = sim.history().last().unwrap();
            println!(
                "t {:.2} depth {:+.4} axial {:+.5} lateral {:.5} {:?} nodes {} needle {}",
                s.time,
                sim.depth_of(s.tip, s.direction),
                s.force.axial,
                s.force.lateral,
                s.state,
                s.active_nodes,
                s.needle_nodes
            );
            if args.get(3).is_some() {
                let n: Vec<String> = sim
                    .needle_nodes()
                    .iter()
                    .map(|n| format!("{:?}/{:?}/{:.4}", n.role, n.friction, n.s))
                    .collect();
                println!("    {}", n.join(" "));
            }
        }
    }
    Ok(())
}

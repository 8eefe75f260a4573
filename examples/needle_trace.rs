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
                let rest = sim.rest_positions();
                let nodes = sim.needle_nodes().to_vec();
                let n: Vec<String> = nodes
                    .iter()
                    .map(|n| {
                        let mut p = [[0.0f32; 4]];
                        let i = n.index as usize;
                        sim.backend()
                            .read(needlesim::NodeField::Position, i..i + 1, &mut p)
                            .unwrap();
                        format!(
                            "{:?}/{:?} x {:.4} x0 {:.4} f {:.3}/{:.3}",
                            n.role, n.friction, p[0][0], rest[i][0], n.axial, n.limit
                        )
                    })
                    .collect();
                println!("    {}", n.join(" "));
            }
        }
    }
    Ok(())
}

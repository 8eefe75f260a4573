//! Metrics of one output frame: energy, displacement, speed and force extremes.

/// Metrics of one output frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrameMetrics {
    /// Frame number.
    pub frame: usize,
    /// Steps taken.
    pub step: u64,
    /// Simulated time in s.
    pub time: f64,
    /// Kinetic energy in J.
    pub kinetic_energy: f64,
    /// Largest distance of a node from its rest position, in m.
    pub max_displacement: f64,
    /// Mean distance of the nodes from their rest positions, in m.
    pub mean_displacement: f64,
    /// Largest node speed in m/s.
    pub max_speed: f64,
    /// Largest elastic force on a node in N.
    pub max_force: f64,
}

impl FrameMetrics {
    /// The metrics of frame `frame` at step `step` from the active nodes' positions,
    /// velocities and forces and the rest positions (mesh nodes first).
    pub fn measure(
        frame: usize,
        step: u64,
        dt: f64,
        pos: &[[f32; 4]],
        vel: &[[f32; 4]],
        force: &[[f32; 4]],
        rest: &[[f64; 3]],
    ) -> FrameMetrics {
        let mut m = FrameMetrics {
            frame,
            step,
            time: step as f64 * dt,
            kinetic_energy: 0.0,
            max_displacement: 0.0,
            mean_displacement: 0.0,
            max_speed: 0.0,
            max_force: 0.0,
        };
        let n = rest.len().min(pos.len());
        for i in 0..pos.len() {
            let sq = |v: [f32; 4]| (0..3).map(|a| (v[a] as f64).powi(2)).sum::<f64>();
            let v2 = sq(vel[i]);
            if pos[i][3] > 0.0 {
                m.kinetic_energy += 0.5 * v2 / pos[i][3] as f64;
            }
            m.max_speed = m.max_speed.max(v2.sqrt());
            m.max_force = m.max_force.max(sq(force[i]).sqrt());
            if i < n {
                let d = (0..3)
                    .map(|a| (pos[i][a] as f64 - rest[i][a]).powi(2))
                    .sum::<f64>()
                    .sqrt();
                m.max_displacement = m.max_displacement.max(d);
                m.mean_displacement += d / n as f64;
            }
        }
        m
    }
}

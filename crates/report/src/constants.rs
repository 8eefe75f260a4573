//! Dimensions and material of the report's reference cases (shared by the cases and the
//! FEM reference data they are compared with).

/// Young's modulus of every reference case, Pa (soft tissue).
pub const YOUNG: f64 = 1e4;
/// Poisson's ratio of every reference case.
pub const POISSON: f64 = 0.3;
/// Density, kg/m^3.
pub const DENSITY: f64 = 1000.0;
/// Relative tolerance of the equilibrium test.
pub const REL_TOL: f64 = 1e-3;
/// Beam width and height, m.
pub const BEAM_WIDTH: f64 = 0.02;
/// Beam length, m (10:1).
pub const BEAM_LENGTH: f64 = 0.2;
/// Euler-Bernoulli tip deflection the cantilever's gravity is scaled to, m (1% of L:
/// linear theory holds).
pub const BEAM_DEFLECTION: f64 = 0.002;
/// Cube side of the stretch and indentation cases, m.
pub const CUBE: f64 = 0.1;
/// Stretch of the stretch case (small: a geometrically nonlinear model's nominal stress
/// differs from linear theory by about `1.5 STRETCH`, 1.5% at a 1% stretch).
pub const STRETCH: f64 = 0.002;
/// Half the side of the square punch, m.
pub const PUNCH_HALF_WIDTH: f64 = 0.025;
/// Punch depth, m: 0.1% of the cube, so that point based animation's Green strain stays
/// close to the linear reference (its punch force differs from Debunne's, whose gradient
/// and volumes it shares, by 0.4% at 15,625 nodes; by 1.25% at 0.5 mm and 5% at 2 mm).
pub const PUNCH_DEPTH: f64 = 0.0001;
/// Radius of the sphere case's ball, m.
pub const SPHERE_RADIUS: f64 = 0.05;
/// Radius of the column case's cylinder, m.
pub const COLUMN_RADIUS: f64 = 0.025;
/// Height of the column case's cylinder, m.
pub const COLUMN_HEIGHT: f64 = 0.1;
/// Gravity of the column case, m/s^2: a uniaxial bar's top would sink `rho g H^2 / (2E)`
/// = 0.1 mm, a strain of at most 0.2% at the clamp (linear theory holds).
pub const COLUMN_GRAVITY: f64 = 0.2;
/// Pressure on the sphere case's ball, Pa: a strain of `-p (1 - 2 nu) / E = -0.1%`, where
/// the geometrically nonlinear models stay within about 0.1% of the linear answer.
pub const SPHERE_PRESSURE: f64 = 25.0;
/// Neighbours per node in every case: 18 completes the first two shells of the cubic
/// lattice (16 drops one face-diagonal pair at every node and makes the lattice models
/// anisotropic).
pub const NEIGHBOURS: usize = 18;

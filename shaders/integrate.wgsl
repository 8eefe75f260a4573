// Symplectic Euler with implicit mass-proportional damping (integrator.rs):
// v <- (v + dt (f w + g)) * damping_factor, x <- x + dt v; w = inverse mass, 0 = fixed.

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read_write> positions: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read_write> velocities: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read> forces: array<vec4<f32>>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = node_index(gid);
    if i >= params.n_active {
        return;
    }
    var x = positions[i];
    if x.w == 0.0 {
        velocities[i] = vec4<f32>(0.0);
        return;
    }
    let f = forces[i];
    let v = (velocities[i].xyz + params.dt * (f.xyz * x.w + params.gravity.xyz)) * params.damping_factor;
    velocities[i] = vec4<f32>(v, 0.0);
    positions[i] = vec4<f32>(x.xyz + params.dt * v, x.w);
}

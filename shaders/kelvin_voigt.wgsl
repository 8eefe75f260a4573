// Kelvin-Voigt tissue viscosity, shared by the Debunne model (debunne_meshfree.wgsl), the
// neo-Hookean model (neo_hookean.wgsl) and point based animation (point_based.wgsl),
// composed after mls.wgsl: the node velocities, their point-set gradient L_i
// (debunne_meshfree.rs::velocity_gradient), the addition of a viscous stress to a node's
// first pass (mls.rs::add_first_pass_stress), and the finite-strain laws' dashpot
// (continuum.rs::finite_viscous_stress).
@group(0) @binding(12) var<storage, read> velocities: array<vec4<f32>>;

fn velocity_gradient(i: u32) -> mat3x3<f32> {
    let vi = velocities[i].xyz;
    let x0i = rest[i].xyz;
    var b = mat3x3<f32>(vec3<f32>(0.0), vec3<f32>(0.0), vec3<f32>(0.0));
    for (var s = 0u; s < params.k; s++) {
        let w = nb_weight[slot(i, s)];
        if w == 0.0 {
            continue;
        }
        let j = nb_index[slot(i, s)];
        let dv = w * (velocities[j].xyz - vi);
        let d0 = rest[j].xyz - x0i;
        b[0] += dv.x * d0;
        b[1] += dv.y * d0;
        b[2] += dv.z * d0;
    }
    return mat_mul(b, a_inv(i));
}

// Adds V_i p A_i^-1 to the linear part of node i's first pass (no integration
// correction: a dashpot's dissipation needs no patch test).
fn add_first_pass_stress(i: u32, p: mat3x3<f32>) {
    let q = rest[i].w * mat_mul(p, a_inv(i));
    let b = FIRST_PASS_VEC4 * i;
    first_pass[b] += vec4<f32>(q[0], q[1].x);
    first_pass[b + 1u] += vec4<f32>(q[1].y, q[1].z, q[2].x, q[2].y);
    first_pass[b + 2u] += vec4<f32>(q[2].z, 0.0, 0.0, 0.0);
}

// The point-set gradients of the positions and of the velocities of node i, one operator
// for both (continuum.rs::point_set_gradients, summed in its order): a rigid spin gives
// F_dot = W F.
struct PointSetGradients {
    f: mat3x3<f32>,
    f_dot: mat3x3<f32>,
}

fn point_set_gradients(i: u32) -> PointSetGradients {
    let xi = positions[i].xyz;
    let vi = velocities[i].xyz;
    let x0i = rest[i].xyz;
    var bx = mat3x3<f32>(vec3<f32>(0.0), vec3<f32>(0.0), vec3<f32>(0.0));
    var bv = mat3x3<f32>(vec3<f32>(0.0), vec3<f32>(0.0), vec3<f32>(0.0));
    for (var s = 0u; s < params.k; s++) {
        let w = nb_weight[slot(i, s)];
        if w == 0.0 {
            continue;
        }
        let j = nb_index[slot(i, s)];
        let d0 = rest[j].xyz - x0i;
        let dx = w * (positions[j].xyz - xi);
        let dv = w * (velocities[j].xyz - vi);
        bx[0] += dx.x * d0;
        bx[1] += dx.y * d0;
        bx[2] += dx.z * d0;
        bv[0] += dv.x * d0;
        bv[1] += dv.y * d0;
        bv[2] += dv.z * d0;
    }
    let a = a_inv(i);
    return PointSetGradients(mat_mul(bx, a), mat_mul(bv, a));
}

// The finite-strain laws' dashpot: P_v = F 2 eta dev(sym(F^T F_dot)), the deviator of the
// Green strain rate pushed by F (frame indifferent), added to node i's first pass.
fn add_finite_viscous(i: u32, eta: f32) {
    if eta <= 0.0 {
        return;
    }
    let g = point_set_gradients(i);
    let f = g.f;
    let c = mat_mul(transpose(f), g.f_dot);
    let e = 0.5 * (c + transpose(c));
    let mean = (e[0].x + e[1].y + e[2].z) / 3.0;
    add_first_pass_stress(i, mat_mul(f, 2.0 * eta * (e - mean * identity())));
}

// The continuum models' shared first-pass code (models/mls.rs): their bindings, the
// moving-least-squares displacement gradient J_i of node i with the hourglass control's
// quadratic fit and the integration correction (J~ = J + T E, consistency.rs), and
// `store`, which packs a stress P_i as [V P A^-1 - G C - c Jf (9 floats), c, c H - G (18
// floats)], G = V P E^T, in seven vec4 per node for gather_force.wgsl. The node volume
// V_i is the w lane of its rest position. Each model's
// shader is composed after this one (and after cluster_frame.wgsl, which reads
// `shape_vector` and `rotation`) and adds its stress and entry points; the `_mixed` entries
// take node i's constants from `node_material` (models::material_row).

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> positions: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> rest: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read> nb_index: array<u32>;
@group(0) @binding(4) var<storage, read> nb_weight: array<f32>;
@group(0) @binding(5) var<storage, read> inverse_moment: array<f32>;
@group(0) @binding(6) var<storage, read_write> first_pass: array<vec4<f32>>;
@group(0) @binding(8) var<storage, read> shape_vector: array<vec4<f32>>;
@group(0) @binding(9) var<storage, read_write> rotation: array<vec4<f32>>;
@group(0) @binding(10) var<storage, read> node_material: array<vec4<f32>>;

struct Gradient {
    j: mat3x3<f32>,
    trace: f32,
    // The quadratic fit's linear part J - H C (rows) and its quadratic part H, column m
    // multiplying monomial m (mls.rs::Gradient). Separate fields, and every loop over the
    // six monomials written out: arrays indexed in a loop went to local memory and made
    // this kernel 3.2 times slower than the first-order one on an H100 (100k nodes).
    fit_j: mat3x3<f32>,
    h0: vec3<f32>,
    h1: vec3<f32>,
    h2: vec3<f32>,
    h3: vec3<f32>,
    h4: vec3<f32>,
    h5: vec3<f32>,
}

// Node i's moment row (mls.rs::MomentRow): A^-1 (row-major, floats 0..9), the quadratic
// basis C (6x3 row-major, 9..27), M^-1 (6x6 upper triangle, 27..48), the integration
// correction E (6x3 row-major, 48..66; consistency.rs).
fn a_inv(i: u32) -> mat3x3<f32> {
    let b = MOMENT_ROW * i;
    return mat3x3<f32>(
        vec3<f32>(inverse_moment[b], inverse_moment[b + 1u], inverse_moment[b + 2u]),
        vec3<f32>(inverse_moment[b + 3u], inverse_moment[b + 4u], inverse_moment[b + 5u]),
        vec3<f32>(inverse_moment[b + 6u], inverse_moment[b + 7u], inverse_moment[b + 8u]),
    );
}

fn basis_row(b: u32, r: u32) -> vec3<f32> {
    let o = b + 9u + 3u * r;
    return vec3<f32>(inverse_moment[o], inverse_moment[o + 1u], inverse_moment[o + 2u]);
}

fn correction_row(b: u32, r: u32) -> vec3<f32> {
    let o = b + 48u + 3u * r;
    return vec3<f32>(inverse_moment[o], inverse_moment[o + 1u], inverse_moment[o + 2u]);
}

fn gradient(i: u32) -> Gradient {
    let xi = positions[i].xyz;
    let x0i = rest[i].xyz;
    var b = mat3x3<f32>(vec3<f32>(0.0), vec3<f32>(0.0), vec3<f32>(0.0));
    var b20 = vec3<f32>(0.0);
    var b21 = vec3<f32>(0.0);
    var b22 = vec3<f32>(0.0);
    var b23 = vec3<f32>(0.0);
    var b24 = vec3<f32>(0.0);
    var b25 = vec3<f32>(0.0);
    var trace = 0.0;
    for (var s = 0u; s < params.k; s++) {
        let w = nb_weight[slot(i, s)];
        if w == 0.0 {
            continue;
        }
        let j = nb_index[slot(i, s)];
        let d = positions[j].xyz - xi;
        let d0 = rest[j].xyz - x0i;
        let du = w * (d - d0);
        b[0] += du.x * d0;
        b[1] += du.y * d0;
        b[2] += du.z * d0;
        b20 += du * (d0.x * d0.x);
        b21 += du * (d0.y * d0.y);
        b22 += du * (d0.z * d0.z);
        b23 += du * (d0.x * d0.y);
        b24 += du * (d0.y * d0.z);
        b25 += du * (d0.z * d0.x);
        trace += w * dot(d0, d0);
    }
    let j = mat_mul(b, a_inv(i));
    // H = (B2 - B C^T) M^-1, and the fit's linear part J - H C.
    let base = MOMENT_ROW * i;
    let m = base + 27u;
    let c0 = basis_row(base, 0u);
    let c1 = basis_row(base, 1u);
    let c2 = basis_row(base, 2u);
    let c3 = basis_row(base, 3u);
    let c4 = basis_row(base, 4u);
    let c5 = basis_row(base, 5u);
    let t0 = b20 - mat_vec(b, c0);
    let t1 = b21 - mat_vec(b, c1);
    let t2 = b22 - mat_vec(b, c2);
    let t3 = b23 - mat_vec(b, c3);
    let t4 = b24 - mat_vec(b, c4);
    let t5 = b25 - mat_vec(b, c5);
    let h0 = t0 * inverse_moment[m + 0u] + t1 * inverse_moment[m + 1u] + t2 * inverse_moment[m + 2u] + t3 * inverse_moment[m + 3u] + t4 * inverse_moment[m + 4u] + t5 * inverse_moment[m + 5u];
    let h1 = t0 * inverse_moment[m + 1u] + t1 * inverse_moment[m + 6u] + t2 * inverse_moment[m + 7u] + t3 * inverse_moment[m + 8u] + t4 * inverse_moment[m + 9u] + t5 * inverse_moment[m + 10u];
    let h2 = t0 * inverse_moment[m + 2u] + t1 * inverse_moment[m + 7u] + t2 * inverse_moment[m + 11u] + t3 * inverse_moment[m + 12u] + t4 * inverse_moment[m + 13u] + t5 * inverse_moment[m + 14u];
    let h3 = t0 * inverse_moment[m + 3u] + t1 * inverse_moment[m + 8u] + t2 * inverse_moment[m + 12u] + t3 * inverse_moment[m + 15u] + t4 * inverse_moment[m + 16u] + t5 * inverse_moment[m + 17u];
    let h4 = t0 * inverse_moment[m + 4u] + t1 * inverse_moment[m + 9u] + t2 * inverse_moment[m + 13u] + t3 * inverse_moment[m + 16u] + t4 * inverse_moment[m + 18u] + t5 * inverse_moment[m + 19u];
    let h5 = t0 * inverse_moment[m + 5u] + t1 * inverse_moment[m + 10u] + t2 * inverse_moment[m + 14u] + t3 * inverse_moment[m + 17u] + t4 * inverse_moment[m + 19u] + t5 * inverse_moment[m + 20u];
    let hc0 = h0.x * c0 + h1.x * c1 + h2.x * c2 + h3.x * c3 + h4.x * c4 + h5.x * c5;
    let hc1 = h0.y * c0 + h1.y * c1 + h2.y * c2 + h3.y * c3 + h4.y * c4 + h5.y * c5;
    let hc2 = h0.z * c0 + h1.z * c1 + h2.z * c2 + h3.z * c3 + h4.z * c4 + h5.z * c5;
    let hc = mat3x3<f32>(hc0, hc1, hc2);
    // The integration correction J~ = J + T E (row a: sum_r t_r[a] e_r), which the stress
    // is taken from; the hourglass fit keeps J.
    let e0 = correction_row(base, 0u);
    let e1 = correction_row(base, 1u);
    let e2 = correction_row(base, 2u);
    let e3 = correction_row(base, 3u);
    let e4 = correction_row(base, 4u);
    let e5 = correction_row(base, 5u);
    let te = mat3x3<f32>(
        t0.x * e0 + t1.x * e1 + t2.x * e2 + t3.x * e3 + t4.x * e4 + t5.x * e5,
        t0.y * e0 + t1.y * e1 + t2.y * e2 + t3.y * e3 + t4.y * e4 + t5.y * e5,
        t0.z * e0 + t1.z * e1 + t2.z * e2 + t3.z * e3 + t4.z * e4 + t5.z * e5,
    );
    return Gradient(j + te, trace, j - hc, h0, h1, h2, h3, h4, h5);
}

fn identity() -> mat3x3<f32> {
    return mat3x3<f32>(vec3<f32>(1.0, 0.0, 0.0), vec3<f32>(0.0, 1.0, 0.0), vec3<f32>(0.0, 0.0, 1.0));
}

// Packs [V P A^-1 - G C - c Jf (9 floats, row-major), c, c H - G (18 floats, column by
// column)] with G = V P E^T, the integration correction's stress terms
// (mls.rs::pack_first_pass), in FIRST_PASS_VEC4 vec4 per node.
fn store(i: u32, p: mat3x3<f32>, g: Gradient, vol: f32, hourglass: f32) {
    let q = mat_mul(p, a_inv(i));
    var c = 0.0;
    if g.trace > 0.0 {
        c = hourglass * vol / g.trace;
    }
    let base = MOMENT_ROW * i;
    let g0 = vol * mat_vec(p, correction_row(base, 0u));
    let g1 = vol * mat_vec(p, correction_row(base, 1u));
    let g2 = vol * mat_vec(p, correction_row(base, 2u));
    let g3 = vol * mat_vec(p, correction_row(base, 3u));
    let g4 = vol * mat_vec(p, correction_row(base, 4u));
    let g5 = vol * mat_vec(p, correction_row(base, 5u));
    let c0 = basis_row(base, 0u);
    let c1 = basis_row(base, 1u);
    let c2 = basis_row(base, 2u);
    let c3 = basis_row(base, 3u);
    let c4 = basis_row(base, 4u);
    let c5 = basis_row(base, 5u);
    let gc0 = g0.x * c0 + g1.x * c1 + g2.x * c2 + g3.x * c3 + g4.x * c4 + g5.x * c5;
    let gc1 = g0.y * c0 + g1.y * c1 + g2.y * c2 + g3.y * c3 + g4.y * c4 + g5.y * c5;
    let gc2 = g0.z * c0 + g1.z * c1 + g2.z * c2 + g3.z * c3 + g4.z * c4 + g5.z * c5;
    let o0 = vol * q[0] - gc0 - c * g.fit_j[0];
    let o1 = vol * q[1] - gc1 - c * g.fit_j[1];
    let o2 = vol * q[2] - gc2 - c * g.fit_j[2];
    let h0 = c * g.h0 - g0;
    let h1 = c * g.h1 - g1;
    let h2 = c * g.h2 - g2;
    let h3 = c * g.h3 - g3;
    let h4 = c * g.h4 - g4;
    let h5 = c * g.h5 - g5;
    let b = FIRST_PASS_VEC4 * i;
    first_pass[b] = vec4<f32>(o0, o1.x);
    first_pass[b + 1u] = vec4<f32>(o1.y, o1.z, o2.x, o2.y);
    first_pass[b + 2u] = vec4<f32>(o2.z, c, h0.x, h0.y);
    first_pass[b + 3u] = vec4<f32>(h0.z, h1);
    first_pass[b + 4u] = vec4<f32>(h2, h3.x);
    first_pass[b + 5u] = vec4<f32>(h3.y, h3.z, h4.x, h4.y);
    first_pass[b + 6u] = vec4<f32>(h4.z, h5);
}


// Viscoelastic state (models/viscoelastic.rs): per node VISCO_ROW floats, S_0 and one
// symmetric tensor per Prony term, six floats each ([xx, yy, zz, xy, yz, zx]), stored
// component-major (float k of node i at k * capacity + i, layout.rs: a warp's threads read
// adjacent words); the committed state first, the next one after it (components
// VISCO_ROW..2 VISCO_ROW), which `visco_commit` copies over after the step.
@group(0) @binding(11) var<storage, read_write> visco: array<f32>;

const VISCO_ROW: u32 = 30u;

fn visco_at(i: u32, k: u32) -> u32 {
    return k * params.slot_stride + i;
}

fn to_sym(m: mat3x3<f32>) -> array<f32, 6> {
    return array<f32, 6>(m[0].x, m[1].y, m[2].z, 0.5 * (m[0].y + m[1].x), 0.5 * (m[1].z + m[2].y), 0.5 * (m[2].x + m[0].z));
}

// The relaxed stress g_inf S_0 + sum h_i of node i's elastic stress s0 (material frame),
// writing its next state (viscoelastic.rs::relax).
fn relax_stress(i: u32, s0: mat3x3<f32>) -> mat3x3<f32> {
    let s = to_sym(s0);
    var s_prev = array<f32, 6>(0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    var total = array<f32, 6>(0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    for (var k = 0u; k < 6u; k++) {
        s_prev[k] = visco[visco_at(i, k)];
        total[k] = params.visco_g_inf * s[k];
    }
    for (var t = 0u; t < params.visco_terms; t++) {
        let at = 6u * (t + 1u);
        for (var k = 0u; k < 6u; k++) {
            let h = params.visco_a[t] * visco[visco_at(i, at + k)] + params.visco_b[t] * (s[k] - s_prev[k]);
            visco[visco_at(i, VISCO_ROW + at + k)] = h;
            total[k] += h;
        }
    }
    for (var k = 0u; k < 6u; k++) {
        visco[visco_at(i, VISCO_ROW + k)] = s[k];
    }
    return mat3x3<f32>(
        vec3<f32>(total[0], total[3], total[5]),
        vec3<f32>(total[3], total[1], total[4]),
        vec3<f32>(total[5], total[4], total[2]),
    );
}

// Commits the viscoelastic state the step's first pass computed.
@compute @workgroup_size(64)
fn visco_commit(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = node_index(gid);
    if i >= params.n_active {
        return;
    }
    let used = 6u * (1u + params.visco_terms);
    for (var k = 0u; k < used; k++) {
        visco[visco_at(i, k)] = visco[visco_at(i, VISCO_ROW + k)];
    }
}

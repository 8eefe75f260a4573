// The continuum models' shared first-pass code (models/mls.rs): their bindings, the
// moving-least-squares displacement gradient J_i of node i with the hourglass control's
// quadratic fit, and `store`, which packs a stress P_i as [V P A^-1 - c Jf (9 floats), c,
// c H (18 floats)] in seven vec4 per node for gather_force.wgsl. The node volume V_i is the w lane of its rest position. Each model's
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
    // multiplying monomial m (mls.rs::Gradient).
    fit_j: mat3x3<f32>,
    h: array<vec3<f32>, 6>,
}

// Node i's moment row (mls.rs::MomentRow): A^-1 (row-major, floats 0..9), the quadratic
// basis C (6x3 row-major, 9..27), M^-1 (6x6 upper triangle, 27..48).
fn a_inv(i: u32) -> mat3x3<f32> {
    let b = MOMENT_ROW * i;
    return mat3x3<f32>(
        vec3<f32>(inverse_moment[b], inverse_moment[b + 1u], inverse_moment[b + 2u]),
        vec3<f32>(inverse_moment[b + 3u], inverse_moment[b + 4u], inverse_moment[b + 5u]),
        vec3<f32>(inverse_moment[b + 6u], inverse_moment[b + 7u], inverse_moment[b + 8u]),
    );
}

fn basis_row(i: u32, r: u32) -> vec3<f32> {
    let b = MOMENT_ROW * i + 9u + 3u * r;
    return vec3<f32>(inverse_moment[b], inverse_moment[b + 1u], inverse_moment[b + 2u]);
}

fn m_inv(i: u32, r: u32, c: u32) -> f32 {
    let lo = min(r, c);
    let hi = max(r, c);
    return inverse_moment[MOMENT_ROW * i + 27u + lo * 6u - lo * (lo + 1u) / 2u + hi];
}

fn gradient(i: u32) -> Gradient {
    let xi = positions[i].xyz;
    let x0i = rest[i].xyz;
    var b = mat3x3<f32>(vec3<f32>(0.0), vec3<f32>(0.0), vec3<f32>(0.0));
    var b2 = array<vec3<f32>, 6>(vec3<f32>(0.0), vec3<f32>(0.0), vec3<f32>(0.0), vec3<f32>(0.0), vec3<f32>(0.0), vec3<f32>(0.0));
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
        b2[0] += du * (d0.x * d0.x);
        b2[1] += du * (d0.y * d0.y);
        b2[2] += du * (d0.z * d0.z);
        b2[3] += du * (d0.x * d0.y);
        b2[4] += du * (d0.y * d0.z);
        b2[5] += du * (d0.z * d0.x);
        trace += w * dot(d0, d0);
    }
    let j = mat_mul(b, a_inv(i));
    // H = (B2 - B C^T) M^-1, and the fit's linear part J - H C.
    var t = array<vec3<f32>, 6>(vec3<f32>(0.0), vec3<f32>(0.0), vec3<f32>(0.0), vec3<f32>(0.0), vec3<f32>(0.0), vec3<f32>(0.0));
    for (var r = 0u; r < 6u; r++) {
        t[r] = b2[r] - mat_vec(b, basis_row(i, r));
    }
    var h = array<vec3<f32>, 6>(vec3<f32>(0.0), vec3<f32>(0.0), vec3<f32>(0.0), vec3<f32>(0.0), vec3<f32>(0.0), vec3<f32>(0.0));
    var hc = mat3x3<f32>(vec3<f32>(0.0), vec3<f32>(0.0), vec3<f32>(0.0));
    for (var col = 0u; col < 6u; col++) {
        var hm = vec3<f32>(0.0);
        for (var r = 0u; r < 6u; r++) {
            hm += t[r] * m_inv(i, r, col);
        }
        h[col] = hm;
        let cr = basis_row(i, col);
        hc[0] += hm.x * cr;
        hc[1] += hm.y * cr;
        hc[2] += hm.z * cr;
    }
    return Gradient(j, trace, j - hc, h);
}

fn identity() -> mat3x3<f32> {
    return mat3x3<f32>(vec3<f32>(1.0, 0.0, 0.0), vec3<f32>(0.0, 1.0, 0.0), vec3<f32>(0.0, 0.0, 1.0));
}

// Packs [V P A^-1 - c Jf (9 floats, row-major), c, c H (18 floats, column by column)]
// (mls.rs::pack_first_pass) in FIRST_PASS_VEC4 vec4 per node.
fn store(i: u32, p: mat3x3<f32>, g: Gradient, vol: f32, hourglass: f32) {
    let q = mat_mul(p, a_inv(i));
    var c = 0.0;
    if g.trace > 0.0 {
        c = hourglass * vol / g.trace;
    }
    let o0 = vol * q[0] - c * g.fit_j[0];
    let o1 = vol * q[1] - c * g.fit_j[1];
    let o2 = vol * q[2] - c * g.fit_j[2];
    let h0 = c * g.h[0];
    let h1 = c * g.h[1];
    let h2 = c * g.h[2];
    let h3 = c * g.h[3];
    let h4 = c * g.h[4];
    let h5 = c * g.h[5];
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

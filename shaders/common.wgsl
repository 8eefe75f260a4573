// Shared by every kernel: the parameter block, the node index of an invocation, and small
// vector, matrix and quaternion helpers. Mirrors crates/core/src/math.rs.

struct Params {
    n_active: u32,
    k: u32,
    iterations: u32,
    groups_x: u32,
    dt: f32,
    damping_factor: f32,
    stiffness: f32,
    spring_damping: f32,
    // w = 1.0, an opaque one for integrate.wgsl's compensated sum.
    gravity: vec4<f32>,
    lambda: f32,
    mu: f32,
    volume_stiffness: f32,
    hourglass: f32,
    slot_stride: u32,
    visco_terms: u32,
    visco_g_inf: f32,
    // Square of the divergence guard's speed bound (integrate.wgsl).
    max_speed_sq: f32,
    visco_a: vec4<f32>,
    visco_b: vec4<f32>,
    viscosity: f32,
    // Hourglass alpha alone (point based animation with several materials).
    hourglass_alpha: f32,
    pad1: f32,
    pad2: f32,
}

const WORKGROUP: u32 = 64u;

// Node handled by an invocation: dispatches wider than the x limit continue along y.
fn node_index(gid: vec3<u32>) -> u32 {
    return gid.x + gid.y * params.groups_x * WORKGROUP;
}

// Element of slot s of node i in the per-slot arrays (neighbour index and weight, rest
// length), stored slot-major so that a warp's threads read adjacent words (layout.rs).
fn slot(i: u32, s: u32) -> u32 {
    return s * params.slot_stride + i;
}

// Floats per node of the continuum models' moment row and vec4 per node of their first
// pass (mls.rs::MOMENT_ROW, FIRST_PASS_ROW / 4).
const MOMENT_ROW: u32 = 66u;
const FIRST_PASS_VEC4: u32 = 7u;

// Row-major 3x3 matrices are stored as mat3x3 whose columns hold the rows (so m[r][c] reads
// row r, column c as in the Rust code); products are written out explicitly.
fn mat_vec(m: mat3x3<f32>, v: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(dot(m[0], v), dot(m[1], v), dot(m[2], v));
}

fn mat_t_vec(m: mat3x3<f32>, v: vec3<f32>) -> vec3<f32> {
    return m[0] * v.x + m[1] * v.y + m[2] * v.z;
}

fn mat_mul(a: mat3x3<f32>, b: mat3x3<f32>) -> mat3x3<f32> {
    // Row r of a*b = sum_t a[r][t] * row t of b.
    return mat3x3<f32>(
        b[0] * a[0].x + b[1] * a[0].y + b[2] * a[0].z,
        b[0] * a[1].x + b[1] * a[1].y + b[2] * a[1].z,
        b[0] * a[2].x + b[1] * a[2].y + b[2] * a[2].z,
    );
}

fn quat_to_mat(q: vec4<f32>) -> mat3x3<f32> {
    let xx = q.x * q.x; let yy = q.y * q.y; let zz = q.z * q.z;
    let xy = q.x * q.y; let xz = q.x * q.z; let yz = q.y * q.z;
    let wx = q.w * q.x; let wy = q.w * q.y; let wz = q.w * q.z;
    return mat3x3<f32>(
        vec3<f32>(1.0 - 2.0 * (yy + zz), 2.0 * (xy - wz), 2.0 * (xz + wy)),
        vec3<f32>(2.0 * (xy + wz), 1.0 - 2.0 * (xx + zz), 2.0 * (yz - wx)),
        vec3<f32>(2.0 * (xz - wy), 2.0 * (yz + wx), 1.0 - 2.0 * (xx + yy)),
    );
}

fn quat_mul(a: vec4<f32>, b: vec4<f32>) -> vec4<f32> {
    return vec4<f32>(
        a.w * b.x + a.x * b.w + a.y * b.z - a.z * b.y,
        a.w * b.y - a.x * b.z + a.y * b.w + a.z * b.x,
        a.w * b.z + a.x * b.y - a.y * b.x + a.z * b.w,
        a.w * b.w - a.x * b.x - a.y * b.y - a.z * b.z,
    );
}

fn quat_rotate(q: vec4<f32>, v: vec3<f32>) -> vec3<f32> {
    let u = q.xyz;
    let t = 2.0 * cross(u, v);
    return v + q.w * t + cross(u, t);
}

// Mueller et al. 2016 rotation extraction, warm started (mueller2016_rotation.rs). `a` is
// row-major (a[r] is row r).
fn extract_rotation(a: mat3x3<f32>, q_in: vec4<f32>, iterations: u32) -> vec4<f32> {
    var q = q_in;
    let ac = transpose(a); // columns of A as rows
    for (var it = 0u; it < iterations; it++) {
        let r = transpose(quat_to_mat(q)); // columns of R as rows
        var omega = vec3<f32>(0.0);
        var d = 0.0;
        for (var c = 0u; c < 3u; c++) {
            omega += cross(r[c], ac[c]);
            d += dot(r[c], ac[c]);
        }
        omega = omega * (1.0 / (abs(d) + 1e-9));
        let angle = length(omega);
        if !(angle >= 1e-6) {
            break;
        }
        q = quat_mul(vec4<f32>(0.5 * omega, 1.0), q);
        q = q / length(q);
    }
    return q;
}

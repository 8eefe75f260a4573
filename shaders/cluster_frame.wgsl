// Shape matching cluster frame of node i (local_shape_matching.rs::cluster_frame): centre
// offset c_i and rotation R_i as a quaternion refined from rotation[i]. Included by kernels
// that declare positions, rest, shape_vector, nb_index, nb_weight and rotation.

struct Frame {
    c: vec3<f32>,
    q: vec4<f32>,
}

fn frame(i: u32) -> Frame {
    let xi = positions[i].xyz;
    let x0i = rest[i].xyz;
    var wsum = 1.0;
    var sd = vec3<f32>(0.0);
    var sd0 = vec3<f32>(0.0);
    var sdd0 = 0.0;
    var m = mat3x3<f32>(vec3<f32>(0.0), vec3<f32>(0.0), vec3<f32>(0.0));
    for (var s = 0u; s < params.k; s++) {
        let w = nb_weight[slot(i, s)];
        if w == 0.0 {
            continue;
        }
        let j = nb_index[slot(i, s)];
        let d = positions[j].xyz - xi;
        let d0 = rest[j].xyz - x0i;
        let wd0 = w * d0;
        sd += w * d;
        sd0 += wd0;
        m[0] += d.x * wd0;
        m[1] += d.y * wd0;
        m[2] += d.z * wd0;
        sdd0 += dot(wd0, d0);
        wsum += w;
    }
    let c = sd * (1.0 / wsum);
    let c0 = -shape_vector[i].xyz;
    let scale = sdd0 - 2.0 * dot(c0, sd0) + wsum * dot(c0, c0);
    var inv = 1.0;
    if scale > 0.0 {
        inv = 1.0 / scale;
    }
    let a = mat3x3<f32>(
        (m[0] - c.x * sd0) * inv,
        (m[1] - c.y * sd0) * inv,
        (m[2] - c.z * sd0) * inv,
    );
    return Frame(c, extract_rotation(a, rotation[i], params.iterations));
}


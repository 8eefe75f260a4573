// The viewer of crates/view: lit 3D geometry (tissue surface, needle), camera-facing node
// markers of a fixed size in pixels, and flat 2D overlays (the force plot inset).
// Every pipeline uses the same vertex: position, a second vector (the normal of lit
// geometry, the pixel offset of a marker corner), and a colour with alpha.

struct Globals {
    // World to clip space.
    view_proj: mat4x4<f32>,
    // Camera position, world space (w unused).
    eye: vec4<f32>,
    // Unit direction towards the light, world space (w unused).
    light: vec4<f32>,
    // Target size in pixels (x, y); z, w unused.
    viewport: vec4<f32>,
};

@group(0) @binding(0) var<uniform> globals: Globals;

struct VertexIn {
    @location(0) position: vec3<f32>,
    @location(1) extra: vec3<f32>,
    @location(2) color: vec4<f32>,
};

struct LitOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) world: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) color: vec4<f32>,
};

struct FlatOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) color: vec4<f32>,
};

@vertex
fn vs_lit(v: VertexIn) -> LitOut {
    var out: LitOut;
    out.clip = globals.view_proj * vec4<f32>(v.position, 1.0);
    out.world = v.position;
    out.normal = v.extra;
    out.color = v.color;
    return out;
}

// Two-sided Blinn-Phong: the normal is turned towards the camera, so that back faces and
// triangles of either winding are lit alike.
@fragment
fn fs_lit(f: LitOut) -> @location(0) vec4<f32> {
    let to_eye = normalize(globals.eye.xyz - f.world);
    var n = f.normal;
    let len = length(n);
    if (len > 0.0) {
        n = n / len;
    } else {
        n = to_eye;
    }
    if (dot(n, to_eye) < 0.0) {
        n = -n;
    }
    let l = globals.light.xyz;
    let diffuse = max(dot(n, l), 0.0);
    let h = normalize(l + to_eye);
    let specular = pow(max(dot(n, h), 0.0), 40.0) * 0.25;
    let rgb = f.color.rgb * (0.35 + 0.65 * diffuse) + vec3<f32>(specular);
    return vec4<f32>(min(rgb, vec3<f32>(1.0)), f.color.a);
}

// A marker corner: the centre projected, then moved by `extra.xy` pixels on screen.
@vertex
fn vs_marker(v: VertexIn) -> FlatOut {
    var out: FlatOut;
    let c = globals.view_proj * vec4<f32>(v.position, 1.0);
    let ndc_offset = v.extra.xy * 2.0 / globals.viewport.xy;
    out.clip = vec4<f32>(c.xy + ndc_offset * c.w, c.z, c.w);
    out.color = v.color;
    return out;
}

// Overlay geometry, already in normalised device coordinates.
@vertex
fn vs_overlay(v: VertexIn) -> FlatOut {
    var out: FlatOut;
    out.clip = vec4<f32>(v.position.xy, 0.0, 1.0);
    out.color = v.color;
    return out;
}

@fragment
fn fs_flat(f: FlatOut) -> @location(0) vec4<f32> {
    return f.color;
}

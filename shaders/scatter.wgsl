// The host's small edits of the component-major arrays (scatter.rs): each write puts one
// 32-bit word `bits` at word `at` of the target array. A node addition or a Tip refresh
// edits a few dozen rows; written one word per slot with `queue.write_buffer`, a row is K
// separate copies, and a refresh issued thousands (13 ms of a step on an NVIDIA H100).
// Batched here, they are one upload and one dispatch. `at == 0xffffffff` pads a batch to
// the storage offset alignment and writes nothing.

struct Write {
    at: u32,
    bits: u32,
}

@group(0) @binding(0) var<storage, read> writes: array<Write>;
@group(0) @binding(1) var<storage, read_write> target_words: array<u32>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if i >= arrayLength(&writes) {
        return;
    }
    let w = writes[i];
    if w.at == 0xffffffffu {
        return;
    }
    target_words[w.at] = w.bits;
}

"""NVIDIA Warp on the peer workload (written for this comparison from workload.py's
description; the CPU device runs a kernel launch on one thread).

    python warp_engine.py WORKLOAD.npz --device cpu|cuda --seconds S

No `from __future__ import annotations` here: Warp before 1.4 reads the kernels' type
annotations as objects and rejects them as strings (1.0.2 is the version that fits a
device run's 64 MiB carry; see docs/guide/performance.md).
"""

import argparse

import numpy as np
import warp as wp

import workload as wl

# The neighbour count as a compile-time constant: Warp unrolls the slot loops.
K = wp.constant(wl.K)


@wp.kernel
def mass_spring_force(
    x: wp.array(dtype=wp.vec3),
    index: wp.array2d(dtype=wp.int32),
    weight: wp.array2d(dtype=wp.float32),
    rest_length: wp.array2d(dtype=wp.float32),
    k: wp.float32,
    f: wp.array(dtype=wp.vec3),
):
    i = wp.tid()
    xi = x[i]
    acc = wp.vec3()
    for s in range(K):
        w = weight[i, s]
        if w != 0.0:
            d = x[index[i, s]] - xi
            length = wp.length(d)
            if length > 0.0:
                inv = 1.0 / length
                acc += (w * (k * (length - rest_length[i, s])) * inv) * d
    f[i] = acc


@wp.kernel
def shape_matching_force(
    x: wp.array(dtype=wp.vec3),
    rest: wp.array(dtype=wp.vec3),
    shape_vector: wp.array(dtype=wp.vec3),
    index: wp.array2d(dtype=wp.int32),
    weight: wp.array2d(dtype=wp.float32),
    k: wp.float32,
    iterations: wp.int32,
    rotation: wp.array(dtype=wp.quat),
    f: wp.array(dtype=wp.vec3),
):
    i = wp.tid()
    xi = x[i]
    x0i = rest[i]
    wsum = float(1.0)
    sd = wp.vec3()
    sd0 = wp.vec3()
    sdd0 = float(0.0)
    m = wp.mat33()
    for s in range(K):
        w = weight[i, s]
        if w != 0.0:
            j = index[i, s]
            d = x[j] - xi
            wd0 = w * (rest[j] - x0i)
            sd += w * d
            sd0 += wd0
            m += wp.outer(d, wd0)
            sdd0 += wp.dot(wd0, rest[j] - x0i)
            wsum += w
    c = sd * (1.0 / wsum)
    c0 = -shape_vector[i]
    scale = sdd0 - 2.0 * wp.dot(c0, sd0) + wsum * wp.dot(c0, c0)
    inv = float(1.0)
    if scale > 0.0:
        inv = 1.0 / scale
    a = (m - wp.outer(c, sd0)) * inv
    q = rotation[i]
    for _ in range(iterations):
        r = wp.quat_to_matrix(q)
        omega = wp.vec3()
        dd = float(0.0)
        for col in range(3):
            rc = wp.vec3(r[0, col], r[1, col], r[2, col])
            ac = wp.vec3(a[0, col], a[1, col], a[2, col])
            omega += wp.cross(rc, ac)
            dd += wp.dot(rc, ac)
        omega = omega * (1.0 / (wp.abs(dd) + 1.0e-9))
        angle = wp.length(omega)
        if angle < 1.0e-6:
            break
        q = wp.quat(0.5 * omega[0], 0.5 * omega[1], 0.5 * omega[2], 1.0) * q
        q = q / wp.length(q)
    rotation[i] = q
    f[i] = k * (c + wp.quat_rotate(q, shape_vector[i]))


@wp.kernel
def integrate(
    x: wp.array(dtype=wp.vec3),
    v: wp.array(dtype=wp.vec3),
    f: wp.array(dtype=wp.vec3),
    inv_mass: wp.array(dtype=wp.float32),
    dt: wp.float32,
    gravity: wp.vec3,
    damp: wp.float32,
):
    i = wp.tid()
    im = inv_mass[i]
    if im == 0.0:
        v[i] = wp.vec3()
    else:
        vel = (v[i] + dt * (f[i] * im + gravity)) * damp
        x[i] = x[i] + dt * vel
        v[i] = vel


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("workload")
    p.add_argument("--device", default="cpu")
    p.add_argument("--seconds", type=float, default=3.0)
    p.add_argument("--repeats", type=int, default=3)
    a = p.parse_args()
    wp.config.quiet = True
    wp.init()
    dev = a.device
    w = wl.load(a.workload)
    kernel, n = w["meta"]["kernel"], len(w["x0"])
    dt = np.float32(w["meta"]["dt"])
    index, weight = w["index"], w["weight"]
    if index.shape[1] != wl.K:
        raise SystemExit(f"the kernels are compiled for K = {wl.K}, the workload has {index.shape[1]}")
    rest = w["rest"]
    x = wp.array(w["x0"], dtype=wp.vec3, device=dev)
    v = wp.zeros(n, dtype=wp.vec3, device=dev)
    f = wp.zeros(n, dtype=wp.vec3, device=dev)
    inv_mass = wp.array(w["inv_mass"], dtype=wp.float32, device=dev)
    idx = wp.array(index, dtype=wp.int32, device=dev)
    wgt = wp.array(weight, dtype=wp.float32, device=dev)
    gravity = wp.vec3(*wl.GRAVITY)
    damp = np.float32(wl.damping_factor(float(dt)))
    if kernel == "mass_spring":
        lengths = np.linalg.norm(rest[index] - rest[:, None, :], axis=2).astype(np.float32)
        rl = wp.array(lengths, dtype=wp.float32, device=dev)
        force = (mass_spring_force, [x, idx, wgt, rl, wl.mass_spring_k(w["meta"]["n"]), f])
    else:
        sv = wp.array(wl.shape_vectors(rest, index, weight), dtype=wp.vec3, device=dev)
        rot = wp.array(np.tile([0.0, 0.0, 0.0, 1.0], (n, 1)).astype(np.float32),
                       dtype=wp.quat, device=dev)
        r0 = wp.array(rest, dtype=wp.vec3, device=dev)
        force = (shape_matching_force,
                 [x, r0, sv, idx, wgt, wl.shape_matching_k(w["meta"]["n"]), wl.ROTATION_ITERATIONS, rot, f])

    def one_step():
        wp.launch(force[0], dim=n, inputs=force[1], device=dev)
        wp.launch(integrate, dim=n, inputs=[x, v, f, inv_mass, dt, gravity, damp], device=dev)

    graph = None
    if wp.get_device(dev).is_cuda:
        # A CUDA graph of a batch of steps: what a user tuning Warp would write.
        with wp.ScopedCapture(device=dev) as cap:
            for _ in range(50):
                one_step()
        graph = cap.graph

    def run(steps: int) -> None:
        if graph is not None:
            for _ in range(steps // 50):
                wp.capture_launch(graph)
            steps %= 50
        for _ in range(steps):
            one_step()
        wp.synchronize_device(dev)

    run(wl.CHECK_STEPS)
    deviation = wl.deviation(x.numpy(), w["reference"], w["x0"])
    rates = wl.measure(run, a.seconds, a.repeats)
    device = wp.get_device(dev).name if wp.get_device(dev).is_cuda else "cpu"
    print(wl.result("warp", wp.__version__, device, 1, rates, deviation))


if __name__ == "__main__":
    main()

"""Taichi on the peer workload (written for this comparison from workload.py's
description), with Taichi's defaults apart from the thread count.

    python taichi_engine.py WORKLOAD.npz --arch cpu|cuda --threads T --seconds S
"""

import argparse

import numpy as np
import taichi as ti

import workload as wl

vec3 = ti.types.vector(3, ti.f32)
vec4 = ti.types.vector(4, ti.f32)
mat3 = ti.types.matrix(3, 3, ti.f32)


@ti.func
def quat_mul(a, b):
    # Hamilton product, (x, y, z, w) storage.
    u, v = a.xyz, b.xyz
    xyz = a.w * v + b.w * u + u.cross(v)
    return vec4(xyz.x, xyz.y, xyz.z, a.w * b.w - u.dot(v))


@ti.func
def quat_matrix(q):
    x, y, z, w = q.x, q.y, q.z, q.w
    return mat3(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


@ti.func
def quat_rotate(q, v):
    u = q.xyz
    t = 2.0 * u.cross(v)
    return v + q.w * t + u.cross(t)


def build(w, arch_threads):
    kernel, n = w["meta"]["kernel"], len(w["x0"])
    kk = w["index"].shape[1]
    dt = float(w["meta"]["dt"])
    gravity = vec3(*wl.GRAVITY)
    damp = float(np.float32(wl.damping_factor(float(dt))))
    x = ti.Vector.field(3, ti.f32, n)
    v = ti.Vector.field(3, ti.f32, n)
    f = ti.Vector.field(3, ti.f32, n)
    inv_mass = ti.field(ti.f32, n)
    index = ti.field(ti.i32, (n, kk))
    weight = ti.field(ti.f32, (n, kk))
    x.from_numpy(w["x0"])
    inv_mass.from_numpy(w["inv_mass"])
    index.from_numpy(w["index"])
    weight.from_numpy(w["weight"])
    rest_np = w["rest"]

    @ti.kernel
    def integrate():
        for i in range(n):
            im = inv_mass[i]
            if im == 0.0:
                v[i] = vec3(0.0, 0.0, 0.0)
            else:
                vel = (v[i] + dt * (f[i] * im + gravity)) * damp
                x[i] = x[i] + dt * vel
                v[i] = vel

    if kernel == "mass_spring":
        rest_length = ti.field(ti.f32, (n, kk))
        rest_length.from_numpy(
            np.linalg.norm(rest_np[w["index"]] - rest_np[:, None, :], axis=2).astype(np.float32)
        )
        k = wl.mass_spring_k(w["meta"]["n"])

        @ti.kernel
        def force():
            for i in range(n):
                xi = x[i]
                acc = vec3(0.0, 0.0, 0.0)
                for s in ti.static(range(kk)):  # unrolled
                    wt = weight[i, s]
                    if wt != 0.0:
                        d = x[index[i, s]] - xi
                        length = d.norm()
                        if length > 0.0:
                            inv = 1.0 / length
                            acc += (wt * (k * (length - rest_length[i, s])) * inv) * d
                f[i] = acc

    else:
        rest = ti.Vector.field(3, ti.f32, n)
        sv = ti.Vector.field(3, ti.f32, n)
        rot = ti.Vector.field(4, ti.f32, n)
        rest.from_numpy(rest_np)
        sv.from_numpy(wl.shape_vectors(rest_np, w["index"], w["weight"]))
        rot.from_numpy(np.tile([0.0, 0.0, 0.0, 1.0], (n, 1)).astype(np.float32))
        k, iterations = wl.shape_matching_k(w["meta"]["n"]), wl.ROTATION_ITERATIONS

        @ti.kernel
        def force():
            for i in range(n):
                xi, x0i = x[i], rest[i]
                wsum = 1.0
                sd = vec3(0.0, 0.0, 0.0)
                sd0 = vec3(0.0, 0.0, 0.0)
                sdd0 = 0.0
                m = mat3(0.0)
                for s in ti.static(range(kk)):  # unrolled
                    wt = weight[i, s]
                    if wt != 0.0:
                        j = index[i, s]
                        d = x[j] - xi
                        d0 = rest[j] - x0i
                        wd0 = wt * d0
                        sd += wt * d
                        sd0 += wd0
                        m += d.outer_product(wd0)
                        sdd0 += wd0.dot(d0)
                        wsum += wt
                c = sd * (1.0 / wsum)
                c0 = -sv[i]
                scale = sdd0 - 2.0 * c0.dot(sd0) + wsum * c0.dot(c0)
                inv = 1.0
                if scale > 0.0:
                    inv = 1.0 / scale
                a = (m - c.outer_product(sd0)) * inv
                q = rot[i]
                for _ in range(iterations):
                    r = quat_matrix(q)
                    omega = vec3(0.0, 0.0, 0.0)
                    dd = 0.0
                    for col in ti.static(range(3)):
                        rc = vec3(r[0, col], r[1, col], r[2, col])
                        ac = vec3(a[0, col], a[1, col], a[2, col])
                        omega += rc.cross(ac)
                        dd += rc.dot(ac)
                    omega = omega * (1.0 / (ti.abs(dd) + 1.0e-9))
                    if omega.norm() < 1.0e-6:
                        break
                    q = quat_mul(vec4(0.5 * omega.x, 0.5 * omega.y, 0.5 * omega.z, 1.0), q)
                    q = q / q.norm()
                rot[i] = q
                f[i] = k * (c + quat_rotate(q, sv[i]))

    def step() -> None:
        force()
        integrate()

    return x, step


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("workload")
    p.add_argument("--arch", default="cpu")
    p.add_argument("--threads", type=int, default=1)
    p.add_argument("--seconds", type=float, default=3.0)
    p.add_argument("--repeats", type=int, default=3)
    a = p.parse_args()
    if a.arch == "cuda":
        ti.init(arch=ti.cuda, default_fp=ti.f32, log_level=ti.WARN)
        # Taichi falls back to the CPU, with a warning, where CUDA does not start: a
        # "CUDA" row must not be a CPU run.
        if ti.lang.impl.current_cfg().arch != ti.cuda:
            raise SystemExit("Taichi could not start on CUDA")
    else:
        ti.init(arch=ti.cpu, cpu_max_num_threads=a.threads, default_fp=ti.f32, log_level=ti.WARN)
    w = wl.load(a.workload)
    x, step = build(w, a.threads)

    def run(steps: int) -> None:
        for _ in range(steps):
            step()
        ti.sync()

    run(wl.CHECK_STEPS)
    deviation = wl.deviation(x.to_numpy(), w["reference"], w["x0"])
    rates = wl.measure(run, a.seconds, a.repeats)
    device = "cuda" if a.arch == "cuda" else "cpu"
    version = ti.__version__
    version = ".".join(map(str, version)) if isinstance(version, tuple) else str(version)
    print(wl.result("taichi", version, device, a.threads, rates, deviation))


if __name__ == "__main__":
    main()

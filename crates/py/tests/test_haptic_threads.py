"""The haptic loop driven from a device thread while the main thread waits in join()
(issue 45): every call from the device thread (set_device, force, running, stop) raised
"Already borrowed" while join() held the object, so the loop ran on a stale pose and
could not be stopped. Now join() holds nothing while it waits."""
import pathlib
import threading
import time

import numpy as np

import needlesim

SCENE = pathlib.Path(__file__).parents[3] / "scenes" / "needle_insert_extract.toml"


def _loop(**kw):
    sim = needlesim.Simulation.from_scene(str(SCENE), backend="cpu")
    return sim, needlesim.HapticLoop(sim, rate=1000.0, **kw)


def test_a_device_thread_sets_the_pose_reads_the_force_and_stops_the_loop_while_main_joins():
    sim, loop = _loop()
    base, direction = np.array(sim.base), np.array(sim.direction)
    errors, forces, poses = [], [], []

    def device():
        try:
            # 1 kHz for 0.6 s: push the needle 2 cm along its axis, then stop the loop.
            t0 = time.perf_counter()
            k = 0
            while (t := time.perf_counter() - t0) < 0.6:
                p = base + direction * (0.02 * t / 0.6)
                loop.set_device(tuple(p), tuple(direction))
                poses.append(p)
                forces.append(np.array(loop.force))
                assert loop.running
                k += 1
                time.sleep(max(0.0, t0 + k * 1e-3 - time.perf_counter()))
            loop.stop()
        except Exception as e:  # noqa: BLE001 - reported below
            errors.append(e)

    th = threading.Thread(target=device)
    th.start()
    stats = loop.join()  # returns once the device thread stops the loop
    th.join(5.0)
    assert not th.is_alive()
    assert errors == [], errors
    assert stats["ticks"] > 300, stats
    assert len(forces) > 300
    # The loop followed the pose the device thread set: the needle advanced.
    assert np.linalg.norm(np.array(sim.base) - base) > 0.015
    assert not loop.running


def test_join_returns_when_the_loop_ends_by_itself_with_a_device_thread_polling():
    sim, loop = _loop(max_ticks=300)
    errors = []
    stop = threading.Event()

    def poll():
        try:
            while not stop.is_set():
                loop.latest()
                loop.running
                loop.stats()
                time.sleep(1e-3)
        except Exception as e:  # noqa: BLE001
            errors.append(e)

    th = threading.Thread(target=poll)
    th.start()
    stats = loop.join()
    stop.set()
    th.join(5.0)
    assert errors == [], errors
    assert stats["ticks"] == 300

"""The haptic loop from Python: a simulated device through the paper scene's surface."""

import os
import time
from pathlib import Path

import numpy as np
import pytest

import needlesim

ROOT = Path(__file__).resolve().parents[3]
PAPER = ROOT / "scenes" / "paper_insertion_lshm.toml"


def test_a_sine_device_punctures_and_the_force_stays_continuous():
    sim = needlesim.Simulation.from_scene(PAPER, threads=1)
    base, direction = sim.base, sim.direction
    device = needlesim.SineDevice(base, direction, amplitude=0.04, frequency=0.25)
    loop = needlesim.HapticLoop(sim, max_ticks=1600, device=device)
    with pytest.raises(RuntimeError, match="HapticLoop is stepping"):
        sim.step(1)
    stats = loop.join()
    assert stats["ticks"] == 1600 and stats["target"] == pytest.approx(1e-3)
    r = loop.records()
    assert r["force"].shape == (1600, 3)
    # The scheduled clock: the device poses are those of the sine, whatever the timing.
    t = r["tick"] * 1e-3
    assert np.allclose(r["device"][:, 0], base[0] + 0.02 * (1 - np.cos(2 * np.pi * 0.25 * t)))
    assert "inside" in r["state"], "the tip punctured the surface within 1.6 s"
    # Continuity through the puncture: the device force changes by at most 0.1 N a tick
    # (the tissue force of this soft cube is below 0.3 N; the coupling spreads its drops).
    assert np.abs(np.diff(r["force"], axis=0)).max() < 0.1
    # The simulation is free again, stepped 1600 ticks of 1 ms.
    assert sim.steps == 1600
    sim.step(1)


def test_the_shared_device_and_bad_settings():
    sim = needlesim.Simulation.from_scene(PAPER, threads=1)
    with pytest.raises(ValueError, match="whole number"):
        needlesim.HapticLoop(sim, rate=1500.0)
    with pytest.raises(ValueError, match="stiffness"):
        needlesim.HapticLoop(sim, stiffness=-1.0)
    with pytest.raises(ValueError, match="clock"):
        needlesim.SineDevice((0, 0, 0), (1, 0, 0), 0.01, 1.0, clock="sundial")
    with pytest.raises(ValueError, match="direction"):
        needlesim.SineDevice((0, 0, 0), (0, 0, 0), 0.01, 1.0)
    loop = needlesim.HapticLoop(sim)
    with pytest.raises(RuntimeError, match="another haptic loop"):
        needlesim.HapticLoop(sim)
    # A bad pose is refused where it is given (it stopped the loop's thread, and the
    # error surfaced only from stop()).
    with pytest.raises(ValueError, match="position must be finite"):
        loop.set_device((float("nan"), 0.0, 0.0), (1.0, 0.0, 0.0))
    with pytest.raises(ValueError, match="direction"):
        loop.set_device((0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    assert loop.running
    base = sim.base
    # Moved 5 mm back, outside the tissue: the needle follows the device (critically
    # damped at 387 rad/s, settled in 0.05 s) and the force returns to zero.
    loop.set_device((base[0] - 0.005, base[1], base[2]), (1.0, 0.0, 0.0))
    time.sleep(0.3)
    f = loop.force
    stats = loop.stop()
    assert stats["ticks"] > 50
    assert np.abs(f).max() < 1e-3, f
    assert sim.base[0] == pytest.approx(base[0] - 0.005, abs=1e-5)
    with pytest.raises(RuntimeError, match="stopped"):
        loop.stop()


def test_a_screenshot_mid_insertion(tmp_path):
    if needlesim.adapter() is None and not os.environ.get("NEEDLESIM_REQUIRE_GPU"):
        pytest.skip("no Vulkan adapter")
    sim = needlesim.Simulation.from_scene(PAPER, threads=1)
    sim.step(1200)
    assert sim.puncture_state == "inside"
    png = tmp_path / "mid.png"
    sim.screenshot(png, width=160, height=120)
    data = png.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    # IHDR: width and height, big-endian, at bytes 16..24.
    assert int.from_bytes(data[16:20], "big") == 160 and int.from_bytes(data[20:24], "big") == 120
    with pytest.raises(ValueError, match="out of range"):
        sim.screenshot(png, width=0, height=10)

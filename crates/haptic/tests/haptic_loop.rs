//! The haptic loop on real scenes: the force sent to the device through a puncture, and
//! the loop's typed errors.

use needlesim::core::scene::BackendChoice;
use needlesim::needle::{PunctureState, Simulation};
use needlesim::{start_simulation, Scene};
use needlesim_haptic::{
    Clock, Device, DeviceError, DevicePose, HapticConfig, HapticError, HapticLoop, SineDevice,
    Tick, TickRecord,
};
use std::sync::{Arc, Mutex};

const SCENES: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../scenes");

fn scene_text(name: &str) -> String {
    let path = format!("{SCENES}/{name}");
    std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path}: {e}"))
}

fn simulation(text: &str) -> Simulation {
    let scene = Scene::from_toml_str(text, std::path::Path::new(SCENES)).expect("scene parses");
    start_simulation(&scene, Some(BackendChoice::Cpu), None)
        .expect("simulation starts")
        .0
}

/// A sinusoidal insertion whose clock is the tick's schedule: the same poses whatever the
/// loop's timing on a loaded machine.
fn sine(sim: &Simulation, amplitude: f64, frequency: f64) -> SineDevice {
    SineDevice::along(
        sim.needle().expect("needle"),
        amplitude,
        frequency,
        Clock::Scheduled,
    )
}

fn largest_step(records: &[TickRecord], f: impl Fn(&TickRecord) -> [f64; 3]) -> (f64, u64) {
    records
        .windows(2)
        .map(|w| {
            let (a, b) = (f(&w[0]), f(&w[1]));
            let d = (0..3).map(|i| (b[i] - a[i]).powi(2)).sum::<f64>().sqrt();
            (d, w[1].index)
        })
        .fold((0.0, 0), |m, x| if x.0 > m.0 { x } else { m })
}

/// The skin of the layered scene gives at 2.8 N and the tissue force falls by about 2 N
/// over the membrane's tear (the scene's 4 ms, [`needlesim::needle::sheath::Tear`]; before issue 39
/// it fell by 1.9 N in one tick). Through the virtual coupling the device feels that drop
/// spread over the ticks the proxy takes to catch up, never more than 0.5 N in one tick;
/// the tissue force itself falls by less than 0.75 N a tick (measured 0.505 N with the
/// default hourglass control, where the skin gives at 2.79 N; about 2 N over the 4 ms
/// tear is 0.5 N a tick on average). The loop runs on the scheduled clock so the
/// machine's load does not change the poses; the scene's automatic step is replaced by
/// 1e-4 s (the 0.99e-4 s it picks is half the critical step) so that a tick is 10 steps.
#[test]
fn the_device_force_is_continuous_through_a_puncture() {
    let text = scene_text("layered_liver_biopsy.toml").replace("dt = \"auto\"", "dt = 1e-4");
    let sim = simulation(&text);
    let device = sine(&sim, 0.03, 0.4);
    let config = HapticConfig {
        max_ticks: Some(1000),
        ..HapticConfig::default()
    };
    let stopped = HapticLoop::start(sim, device, config)
        .expect("loop starts")
        .join()
        .expect("loop joins");
    assert!(stopped.error.is_none(), "{:?}", stopped.error);
    let r = &stopped.records;
    assert_eq!(r.len(), 1000);
    let inside = r.iter().position(|t| t.state == PunctureState::Inside);
    let inside = inside.expect("the skin is punctured within 1000 ticks");
    let peak = r[..inside]
        .iter()
        .map(|t| t.tissue[0].abs())
        .fold(0.0, f64::max);
    let (tissue_step, at) = largest_step(r, |t| t.tissue);
    let (device_step, dat) = largest_step(r, |t| t.force);
    println!(
        "puncture at tick {inside}: peak tissue force {peak:.3} N, largest tissue step \
         {tissue_step:.3} N (tick {at}), largest device step {device_step:.3} N (tick {dat})"
    );
    assert!(
        peak > 2.0,
        "the skin was pressed to its puncture force: {peak} N"
    );
    let after = r[inside..(inside + 50).min(r.len())]
        .iter()
        .map(|t| t.tissue[0].abs())
        .fold(f64::INFINITY, f64::min);
    assert!(
        peak - after > 1.5,
        "the tissue force drops at the puncture: {peak} N to {after} N within 50 ticks"
    );
    assert!(
        tissue_step < 0.75,
        "the tear spreads the drop: largest tissue step {tissue_step} N"
    );
    assert!(
        device_step < 0.5,
        "device force step {device_step} N at tick {dat}"
    );
    // The device ends up feeling the tissue: after the proxy settled (100 ticks after the
    // puncture, 15 time constants of the critically damped coupling at 387 rad/s), the
    // force sent and the tissue force agree within the drag C v and the change of the
    // tissue force over a few ticks.
    let settled = &r[inside + 100];
    let diff = (settled.force[0] - settled.tissue[0]).abs();
    assert!(
        diff < 0.1,
        "device {:?} tissue {:?}",
        settled.force,
        settled.tissue
    );
}

/// A device that fails after a few ticks, recording what it was sent.
struct Faulty {
    ticks: u64,
    sent: Arc<Mutex<Vec<[f64; 3]>>>,
    pose: [f64; 3],
}

impl Device for Faulty {
    fn pose(&mut self, tick: &Tick) -> Result<DevicePose, DeviceError> {
        if tick.index == self.ticks {
            return Err(DeviceError("cable unplugged".into()));
        }
        Ok(DevicePose::now(self.pose, [1.0, 0.0, 0.0]))
    }

    fn render(&mut self, force: [f64; 3], _tick: &Tick) -> Result<(), DeviceError> {
        self.sent.lock().unwrap().push(force);
        Ok(())
    }
}

/// Bad settings and failures are typed, and a failing loop sends zero force last.
#[test]
fn the_loop_names_what_is_wrong() {
    let text = scene_text("paper_insertion_lshm.toml");
    let start = |config: HapticConfig| {
        let sim = simulation(&text);
        let d = sine(&sim, 0.01, 1.0);
        HapticLoop::start(sim, d, config).err()
    };
    let e = start(HapticConfig {
        rate: 1500.0,
        ..HapticConfig::default()
    });
    assert!(matches!(e, Some(HapticError::Rate { .. })), "{e:?}");
    // 0 Hz, and rates so low that one tick ran millions of steps `stop` waited for.
    for rate in [0.0, 1e-3, 1e-300, 0.5] {
        let e = start(HapticConfig {
            rate,
            ..HapticConfig::default()
        });
        assert!(
            matches!(e, Some(HapticError::Setting { name: "rate", .. })),
            "{rate}: {e:?}"
        );
        // In e-notation when tiny (1e-300 Hz printed 300 digits).
        let text = e.unwrap().to_string();
        assert!(text.len() < 300, "{text}");
    }
    let mut c = HapticConfig::default();
    c.coupling.stiffness = -1.0;
    let e = start(c);
    assert!(
        matches!(
            e,
            Some(HapticError::Setting {
                name: "stiffness",
                ..
            })
        ),
        "{e:?}"
    );
    let e = start(HapticConfig {
        lowpass: Some(f64::NAN),
        ..HapticConfig::default()
    });
    assert!(
        matches!(
            e,
            Some(HapticError::Setting {
                name: "lowpass",
                ..
            })
        ),
        "{e:?}"
    );

    // No needle to hold.
    let sim = simulation(&scene_text("cube_sag_lshm.toml"));
    let d = SineDevice {
        start: [0.0; 3],
        direction: [1.0, 0.0, 0.0],
        amplitude: 0.0,
        frequency: 1.0,
        clock: Clock::Scheduled,
    };
    let e = HapticLoop::start(sim, d, HapticConfig::default()).err();
    assert!(matches!(e, Some(HapticError::NoNeedle)), "{e:?}");

    // A device held 5 mm off the needle's base pulls with the spring, then fails: the
    // error names the tick and the last force sent is zero.
    let sim = simulation(&text);
    let base = sim.needle().unwrap().base();
    let sent = Arc::new(Mutex::new(Vec::new()));
    let dev = Faulty {
        ticks: 20,
        sent: sent.clone(),
        pose: [base[0] + 0.005, base[1], base[2]],
    };
    let stopped = HapticLoop::start(sim, dev, HapticConfig::default())
        .unwrap()
        .join()
        .unwrap();
    let e = stopped.error;
    assert!(
        matches!(e, Some(HapticError::Device { tick: 20, .. })),
        "{e:?}"
    );
    let sent = sent.lock().unwrap();
    assert_eq!(sent.len(), 21);
    assert!(
        sent[0][0] < -0.5,
        "the spring pulls the device back: {:?}",
        sent[0]
    );
    assert_eq!(sent[20], [0.0; 3]);

    // A pose that is not finite stops the loop the same way.
    let sim = simulation(&text);
    let dev = Faulty {
        ticks: u64::MAX,
        sent: Arc::default(),
        pose: [f64::NAN, 0.0, 0.0],
    };
    let stopped = HapticLoop::start(sim, dev, HapticConfig::default())
        .unwrap()
        .join()
        .unwrap();
    assert!(
        matches!(stopped.error, Some(HapticError::Pose { tick: 0, .. })),
        "{:?}",
        stopped.error
    );
}

/// Saturation scales the force down to the limit and counts the ticks.
#[test]
fn a_saturated_force_is_capped_and_counted() {
    let sim = simulation(&scene_text("paper_insertion_lshm.toml"));
    let base = sim.needle().unwrap().base();
    let dev = Faulty {
        ticks: 50,
        sent: Arc::default(),
        pose: [base[0] + 0.02, base[1], base[2]],
    };
    let config = HapticConfig {
        max_force: 1.0,
        ..HapticConfig::default()
    };
    let stopped = HapticLoop::start(sim, dev, config).unwrap().join().unwrap();
    // 2 cm at 300 N/m: 6 N asked, 1 N sent, from the first tick on.
    let first = stopped.records[0];
    assert!(first.saturated);
    assert!((first.force[0] + 1.0).abs() < 1e-12, "{:?}", first.force);
    assert_eq!(
        stopped.stats.saturated,
        stopped.records.iter().filter(|r| r.saturated).count() as u64
    );
    // The free proxy catches up with the device in about 7 ticks (critically damped at
    // 387 rad/s from 20 mm to the 3.3 mm that 1 N takes).
    assert!(stopped.stats.saturated >= 3, "{:?}", stopped.stats);
    for r in &stopped.records {
        let f = r.force.iter().map(|v| v * v).sum::<f64>().sqrt();
        assert!(f <= 1.0 + 1e-12, "tick {}: {f} N", r.index);
    }
}

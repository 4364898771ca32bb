//! Integration tests on real MuJoCo: the built-in models, stand, and small
//! sweeps in both modes. They embed CPython and find the project venv the way
//! the `pupper` binary does.

use std::sync::Once;

use pupper_core::plan::config::{Defaults, SweepConfig};
use pupper_core::plan::grid::Grid;
use pupper_core::plan::mode::Mode;
use pupper_core::plan::schedule::Schedule;
use pupper_core::request::spec::SweepSpec;
use pupper_core::robot::model::ModelSource;
use pupper_core::sim::metrics::Status;
use pupper_core::sim::runner::{self, CellResult, NoHooks, RunOptions};
use pupper_mujoco::{api, bridge};

fn init() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        let python = pupper_mujoco::embed::find_python(option_env!("PYO3_PYTHON"));
        pupper_mujoco::embed::start(python.as_deref());
    });
}

fn builtin(name: &str) -> ModelSource {
    ModelSource::parse(name).unwrap()
}

#[test]
fn builtin_models_have_the_expected_sizes() {
    init();
    let f = api::info(
        &builtin("pupper_v3"),
        &pupper_core::robot::variant::VARIANTS[0],
    )
    .unwrap();
    assert_eq!((f.nq, f.nv, f.nu, f.nbody), (19, 18, 12, 14));
    assert_eq!(f.joints[0].kind, "free");
    assert_eq!(f.actuators[0].name, "leg_front_r_1");
    assert_eq!(f.actuators[11].name, "leg_back_l_3");
    assert_eq!(f.actuators[0].kp_kd(), (5.0, 0.1));
    assert_eq!(f.actuators[0].forcerange, Some([-3.0, 3.0]));
    assert_eq!(f.keyframes[0].name, "home");
    assert_eq!(f.keyframes[0].qpos[2], 0.28);
    assert_eq!(f.sensors.len(), 7);
    assert!((f.total_mass - 3.17).abs() < 1e-9, "{}", f.total_mass);
    let x = api::info(
        &builtin("pupper_v3_fixed"),
        &pupper_core::robot::variant::VARIANTS[0],
    )
    .unwrap();
    assert_eq!((x.nq, x.nv, x.nu, x.nbody), (12, 12, 12, 14));
}

#[test]
fn stand_settles_at_the_reference_height() {
    init();
    let r = api::stand(&SweepSpec::stand()).unwrap();
    assert!((r.final_z - 0.120).abs() < 0.0005, "{}", r.final_z);
    assert_eq!(r.status, Status::Ok);
    assert!(r.last_1s_std_mm < 0.01);
}

#[test]
fn stand_needs_a_floating_base() {
    init();
    let e = api::stand(&SweepSpec {
        model: "pupper_v3_fixed".into(),
        seconds: 1.0,
        ..SweepSpec::stand()
    })
    .unwrap_err();
    assert!(e.to_string().contains("no free-joint base"), "{e}");
    assert!(e.is_user_error());
}

fn small_sweep(mode: Mode, threads: usize, chunk_cells: usize) -> Vec<CellResult> {
    let cfg = SweepConfig {
        integrator: None,
        model: builtin("pupper_v3"),
        grid: Grid::parse(&["kp=10,60", "kd=0.5,2"]).unwrap(),
        // 4 s: the push at 2 s and the 1.5 s after it fit
        schedule: Schedule {
            duration: 4.0,
            ..Schedule::default()
        },
        mode,
        defaults: Defaults::default(),
        replicates: Default::default(),
        backend: Default::default(),
        experiment: pupper_core::plan::experiment::Experiment::Stand,
        motor: Default::default(),
    };
    let opts = RunOptions {
        threads,
        chunk_cells: Some(chunk_cells),
        ..RunOptions::default()
    };
    run(&cfg, opts)
}

/// Every cell of `cfg` on the CPU backend.
fn run(cfg: &SweepConfig, opts: RunOptions) -> Vec<CellResult> {
    bridge::with_model(&cfg.model, true, |m| {
        runner::run_cells(m, cfg, &cfg.grid.cells(), opts, &mut NoHooks)
    })
    .unwrap()
}

#[test]
fn sweeps_in_both_modes_stand_and_reject_the_push() {
    init();
    for mode in [Mode::Servo, Mode::Torque] {
        let r = small_sweep(mode, 0, 256);
        assert_eq!(r.len(), 4);
        for c in &r {
            assert_eq!(c.metrics.status, Status::Ok, "{mode:?} {}", c.cell.id);
            assert!(
                c.metrics.final_z > 0.1 && c.metrics.final_z < 0.14,
                "{}",
                c.metrics.final_z
            );
            assert!(c.metrics.push_dip_mm > 0.0, "the push must show");
            assert!(c.metrics.peak_torque <= 3.0 + 1e-9);
        }
        // stiffer legs dip less
        assert!(r[2].metrics.push_dip_mm < r[0].metrics.push_dip_mm);
    }
}

#[test]
fn numbers_do_not_depend_on_threads_or_chunking() {
    init();
    for mode in [Mode::Servo, Mode::Torque] {
        let a = small_sweep(mode, 1, 256);
        let b = small_sweep(mode, 2, 1);
        for (x, y) in a.iter().zip(&b) {
            assert_eq!(x.cell, y.cell);
            // bit for bit: NaN-free metrics compare equal
            assert_eq!(format!("{:?}", x.metrics), format!("{:?}", y.metrics));
        }
    }
}

#[test]
fn a_broken_model_is_a_model_error() {
    init();
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("broken.xml");
    std::fs::write(&p, "<mujoco><worldbody><body></mujoco>").unwrap();
    let source = ModelSource::parse(p.to_str().unwrap()).unwrap();
    let e = api::info(&source, &pupper_core::robot::variant::VARIANTS[0]).unwrap_err();
    assert_eq!(e.kind(), pupper_core::ErrorKind::Model, "{e}");
    assert!(!e.to_string().contains('\n'), "one line: {e}");
}

#[test]
fn body_variants_change_the_stance() {
    init();
    // leg_scale and torso_mass_scale give per-cell models (set_models)
    let cfg = SweepConfig {
        integrator: None,
        model: builtin("pupper_v3"),
        grid: Grid::parse(&["leg_scale=1,1.5", "torso_mass_scale=1,2"]).unwrap(),
        schedule: Schedule {
            duration: 3.0,
            push: None,
            ..Schedule::default()
        },
        mode: Mode::Servo,
        defaults: Defaults::default(),
        replicates: Default::default(),
        backend: Default::default(),
        experiment: pupper_core::plan::experiment::Experiment::Stand,
        motor: Default::default(),
    };
    let r = run(&cfg, RunOptions::default());
    let z: Vec<f64> = r.iter().map(|c| c.metrics.final_z).collect();
    assert!(r.iter().all(|c| c.metrics.status == Status::Ok));
    // the unscaled cell is the plain model
    assert!((z[0] - 0.1198).abs() < 1e-3, "{z:?}");
    // longer legs stand taller, a heavier torso sags
    assert!(z[2] > z[0] + 0.02, "{z:?}");
    assert!(z[1] < z[0], "{z:?}");
    assert!(z[3] < z[2], "{z:?}");
}

/// A cluster worker's task: the same numbers as the local runner, bit for
/// bit through the wire format; and a worker that would give other numbers
/// (another pupper or mujoco, another model file) refuses, naming the fix.
#[test]
fn a_cluster_task_gives_the_local_numbers_or_refuses() {
    use pupper_core::sim::cluster::{self, Job, Outcome, Task};
    init();
    let cfg = SweepConfig {
        integrator: None,
        model: builtin("pupper_v3"),
        grid: Grid::parse(&["kp=10,60", "kd=0.5,2"]).unwrap(),
        schedule: Schedule {
            duration: 2.0,
            ..Schedule::default()
        },
        ..SweepConfig::default()
    };
    let local = run(&cfg, RunOptions::default());
    let (sha, mujoco) = bridge::with_model(&cfg.model, true, |m| {
        Ok((m.info().sha256.clone(), m.mujoco_version().to_string()))
    })
    .unwrap();
    let job = Job {
        config: cfg.clone(),
        model_sha256: sha,
        pupper_version: pupper_core::VERSION.into(),
        mujoco_version: mujoco,
        chunk_steps: RunOptions::default().chunk_steps,
    };
    // the last three cells, as a task
    let task = cluster::encode(&Task {
        cells: cfg.grid.cells()[1..].to_vec(),
    })
    .unwrap();
    let outcome = |job: &Job| -> Outcome {
        let bytes = api::run_task(&cluster::encode(job).unwrap(), &task, 2).unwrap();
        cluster::decode(&bytes).unwrap()
    };
    let Outcome::Done(got) = outcome(&job) else {
        panic!("the task failed")
    };
    assert_eq!(got.len(), 3);
    for (g, l) in got.iter().zip(&local[1..]) {
        assert_eq!(g.cell, l.cell);
        assert_eq!(format!("{:?}", g.metrics), format!("{:?}", l.metrics));
    }
    let refusal = |job: Job, words: &str| match outcome(&job) {
        Outcome::Failed { user, message, .. } => {
            assert!(user && message.contains(words), "{message}");
        }
        Outcome::Done(_) => panic!("a worker unlike the driver ran the task"),
    };
    refusal(
        Job {
            model_sha256: "0123456789abcdef".into(),
            ..job.clone()
        },
        "is not the driver's (SHA-256",
    );
    refusal(
        Job {
            pupper_version: "0.0.1".into(),
            ..job.clone()
        },
        "the driver 0.0.1: install the same pupper_core",
    );
    refusal(
        Job {
            mujoco_version: "3.3.0".into(),
            ..job
        },
        "the driver 3.3.0",
    );
}

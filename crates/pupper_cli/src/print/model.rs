//! The model commands' printouts: `info`, `stand`, `doctor`, `pose`
//! (`gains` has its own file).

use std::fmt::Write;

use pupper_core::robot::model::ModelInfo;
use pupper_mujoco::api::StandReport;
use pupper_mujoco::bridge::PythonReport;

/// `pupper info`: sizes, joints, actuators, keyframes, sensors, legs.
pub fn info(m: &ModelInfo) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "model      {} ({})", m.name, m.source);
    let _ = writeln!(s, "sha256     {}", m.sha256);
    let _ = writeln!(
        s,
        "sizes      nq {}  nv {}  nu {}  nbody {}",
        m.nq, m.nv, m.nu, m.nbody
    );
    let _ = writeln!(s, "timestep   {} s", m.timestep);
    let _ = writeln!(s, "total mass {:.3} kg", m.total_mass);
    joints(&mut s, m);
    actuators(&mut s, m);
    let _ = writeln!(s, "\nkeyframes ({})", m.keyframes.len());
    for k in &m.keyframes {
        let head: Vec<String> = k.qpos.iter().take(7).map(|v| format!("{v}")).collect();
        let more = if k.qpos.len() > 7 { " ..." } else { "" };
        let _ = writeln!(s, "  {:<10} qpos [{}{more}]", k.name, head.join(" "));
    }
    let _ = writeln!(s, "\nsensors ({})", m.sensors.len());
    for x in &m.sensors {
        let _ = writeln!(s, "  {:<18} {:<14} dim {}", x.name, x.kind, x.dim);
    }
    legs(&mut s, m);
    s
}

/// The joints: name, type, addresses, range.
fn joints(s: &mut String, m: &ModelInfo) {
    let _ = writeln!(s, "\njoints ({})", m.joints.len());
    let _ = writeln!(
        s,
        "  {:<18} {:<6} {:>4} {:>4}  range (rad)",
        "name", "type", "qpos", "qvel"
    );
    for j in &m.joints {
        let range = j
            .range
            .map(|r| format!("[{:.2}, {:.2}]", r[0], r[1]))
            .unwrap_or_else(|| "-".into());
        let _ = writeln!(
            s,
            "  {:<18} {:<6} {:>4} {:>4}  {}",
            j.name, j.kind, j.qpos_adr, j.dof_adr, range
        );
    }
}

/// The actuators in ctrl order: joint, group, own gains, torque limit.
fn actuators(s: &mut String, m: &ModelInfo) {
    let _ = writeln!(s, "\nactuators in ctrl order ({})", m.actuators.len());
    let _ = writeln!(
        s,
        "  {:>3} {:<18} {:<18} {:<5} {:>7} {:>7}  torque limit (N·m)",
        "ctrl", "name", "joint", "group", "kp", "kd"
    );
    let mut motors = 0;
    for (i, a) in m.actuators.iter().enumerate() {
        let joint = a
            .joint
            .and_then(|j| m.joints.get(j))
            .map(|j| j.name.as_str())
            .unwrap_or("-");
        // a motor has no servo gains of its own: what a run gives it is used
        let (kp, kd) = match a.own_gains() {
            Some([kp, kd]) => (kp.to_string(), kd.to_string()),
            None => {
                motors += 1;
                ("-".into(), "-".into())
            }
        };
        // the limit a run clips at: the force range, else the control range
        let fr = match (a.forcerange, a.ctrlrange) {
            (Some(r), _) => format!("[{}, {}]", r[0], r[1]),
            (None, Some(r)) => format!("[{}, {}] (ctrlrange)", r[0], r[1]),
            (None, None) => "unlimited".into(),
        };
        // what the joint does in its leg, measured: the group its gain axes use
        let group = m.actuator_group(i).unwrap_or("-");
        let _ = writeln!(
            s,
            "  {i:>3}  {:<18} {:<18} {group:<5} {kp:>7} {kd:>7}  {fr}",
            a.name, joint
        );
    }
    if motors > 0 {
        let _ = writeln!(
            s,
            "  -: a motor, no servo gains of its own: a run uses --kp/--kd (or a kp/kd grid)"
        );
    }
}

/// Each leg measured on the compiled body at the default pose.
fn legs(s: &mut String, m: &ModelInfo) {
    if !m.legs.is_empty() {
        let _ = writeln!(
            s,
            "\nlegs at the default pose (world m; hip = hip-flexion joint)"
        );
        let p = |v: [f64; 3]| format!("({:+.4}, {:+.4}, {:+.4})", v[0], v[1], v[2]);
        for l in &m.legs {
            let _ = writeln!(
                s,
                "  {:<16} hip-to-foot {:.4}  hip {}  knee {}  foot {}",
                l.name,
                l.hip_to_foot,
                p(l.hip),
                p(l.knee),
                p(l.foot)
            );
        }
    }
}

pub fn stand(r: &StandReport) -> String {
    // a quantity the run was too short to measure (see the note) is "-"
    let num = |v: f64, d: usize| {
        if v.is_nan() {
            "-".to_string()
        } else {
            format!("{v:.d$}")
        }
    };
    format!(
        "stand  {} ({} mode, {}, {} s, no push)\n  final z          {} m\n  last-1s std      {} mm\n  max tilt         {} deg\n  status           {}\n",
        r.model,
        r.mode.as_str(),
        r.gains,
        r.seconds,
        num(r.final_z, 4),
        num(r.last_1s_std_mm, 3),
        num(r.max_tilt_deg, 2),
        r.status.as_str()
    )
}

pub fn doctor(r: &PythonReport) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "python     {}", r.executable);
    let _ = writeln!(s, "version    {}", r.version);
    let _ = writeln!(s, "prefix     {}", r.prefix);
    let _ = writeln!(s, "base       {}", r.base_prefix);
    let _ = writeln!(
        s,
        "numpy      {}",
        r.numpy.as_deref().unwrap_or("not found")
    );
    match (&r.mujoco, &r.mujoco_path) {
        (Some(v), Some(p)) => {
            let _ = writeln!(s, "mujoco     {v} ({p})");
        }
        _ => {
            let _ = writeln!(s, "mujoco     not usable");
        }
    }
    match (&r.warp, &r.warp_problem) {
        (Some(v), _) => {
            let _ = writeln!(s, "warp       {v}");
            let _ = writeln!(s, "devices    {}", r.warp_devices.join(", "));
        }
        (None, Some(p)) => {
            let _ = writeln!(s, "warp       not usable (--backend warp): {p}");
        }
        (None, None) => {}
    }
    let _ = writeln!(
        s,
        "ray        {}",
        r.ray.as_deref().unwrap_or(
            "not installed (--ray needs it: pip install 'pupper_core[ray]', or make setup PUPPER_EXTRAS=ray)"
        )
    );
    s
}

pub fn pose(p: &pupper_core::robot::pose::StandPose) -> String {
    let mut s = String::new();
    let why = match p.depth_from {
        "given" => "as given".to_string(),
        _ => format!(
            "the chapter's 0.14 m scaled to legs of {:.3} m",
            p.leg_length
        ),
    };
    let _ = writeln!(
        s,
        "stand pose: hip {:.3} rad, knee {:.3} rad (first leg's convention), thigh {:.3} rad from vertical",
        p.hfe, p.kfe, p.thigh_angle
    );
    let _ = writeln!(
        s,
        "target: feet {:.4} m below the hips ({why})",
        -p.target_z
    );
    let _ = writeln!(
        s,
        "base height {:.4} m (lowest foot just above the floor)",
        p.base_z
    );
    let _ = writeln!(s, "reached, each foot from its hip:");
    for (name, x, z) in &p.feet {
        let _ = writeln!(s, "  {name:<16} depth {:.4} m  x {:+.4} m", -z, x);
    }
    let t: Vec<String> = p.targets.iter().map(|v| format!("{v:.4}")).collect();
    let _ = writeln!(s, "targets (actuator order): {}", t.join(","));
    s
}

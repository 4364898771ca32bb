fn main() {
    let py = pupper_core::embed::find_python(option_env!("PUPPER_BUILD_PYTHON"));
    pupper_core::embed::start(py.as_deref());
    let r = pupper_core::bridge::doctor().unwrap();
    println!("{r:?}");
    let info = pupper_core::api::info(&Default::default()).unwrap();
    println!(
        "{} {} {} {} {}",
        info.nq, info.nv, info.nu, info.nbody, info.total_mass
    );
    let t = std::time::Instant::now();
    let s = pupper_core::api::stand(
        &Default::default(),
        10.0,
        5.0,
        0.1,
        pupper_core::schedule::InitialState::Keyframe("home".into()),
        pupper_core::physics::Mode::Servo,
    )
    .unwrap();
    println!("{s:?} {:?}", t.elapsed());
}

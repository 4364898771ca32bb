//! Randomized replicates: what may vary between plausible robots, how it is
//! written (`torso_mass=±10%`, `friction=0.5:1.2`, `q_noise=N(0,0.002)`,
//! `delay=0:3`), and the draws themselves.
//!
//! Every draw comes from its own generator, keyed by (seed, cell id,
//! replicate, quantity, index) through SHA-256 into ChaCha8: no shared
//! stream, so the numbers do not depend on threads, batches, shards, resume
//! points or the order cells run in.

use rand_chacha::ChaCha8Rng;
use rand_chacha::rand_core::SeedableRng;
use rand_distr::{Distribution, Normal, Uniform};
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

use crate::error::{Error, Result};
use crate::plan::mode::Mode;

/// What a replicate may vary.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Quantity {
    /// Torso mass and inertia (relative).
    TorsoMass,
    /// Thigh and calf masses (relative).
    LegMass,
    /// Each actuator's gain (relative, drawn per joint).
    MotorGain,
    /// Sliding friction of the feet and floor (a range).
    Friction,
    /// The push's vertical force (N, a range).
    PushForce,
    /// When the push starts (s, a range).
    PushAt,
    /// Gaussian noise on the joint angles the torque-mode PD reads (rad).
    QNoise,
    /// Observation latency of the torque-mode PD (whole control steps).
    Delay,
    /// The servo firmware's command delay (s; `--motor delay`).
    MotorDelay,
    /// The firmware's derivative filter cutoff (Hz; `--motor filter`).
    MotorFilter,
    /// The motor's no-load speed (rad/s; `--motor noload`).
    MotorNoload,
    /// The torque's first-order lag behind the PD (s; `--motor lag`).
    MotorLag,
}

impl Quantity {
    pub const ALL: [Quantity; 12] = [
        Quantity::TorsoMass,
        Quantity::LegMass,
        Quantity::MotorGain,
        Quantity::Friction,
        Quantity::PushForce,
        Quantity::PushAt,
        Quantity::QNoise,
        Quantity::Delay,
        Quantity::MotorDelay,
        Quantity::MotorFilter,
        Quantity::MotorNoload,
        Quantity::MotorLag,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Quantity::TorsoMass => "torso_mass",
            Quantity::LegMass => "leg_mass",
            Quantity::MotorGain => "motor_gain",
            Quantity::Friction => "friction",
            Quantity::PushForce => "push_force",
            Quantity::PushAt => "push_at",
            Quantity::QNoise => "q_noise",
            Quantity::Delay => "delay",
            Quantity::MotorDelay => "motor_delay",
            Quantity::MotorFilter => "motor_filter",
            Quantity::MotorNoload => "motor_noload",
            Quantity::MotorLag => "motor_lag",
        }
    }

    /// How it may be written, for messages.
    fn forms(self) -> &'static str {
        match self {
            Quantity::TorsoMass | Quantity::LegMass | Quantity::MotorGain => "±P% (e.g. ±10%)",
            Quantity::Friction => "LOW:HIGH with 0 < LOW <= HIGH (e.g. 0.5:1.2)",
            Quantity::PushForce => "LOW:HIGH newtons (e.g. -35:-15)",
            Quantity::PushAt => "LOW:HIGH seconds, LOW >= 0 (e.g. 1.5:3)",
            Quantity::QNoise => "N(0,SIGMA) radians (e.g. N(0,0.002))",
            Quantity::Delay => "LOW:HIGH whole control steps, LOW >= 0 (e.g. 0:3)",
            Quantity::MotorDelay => "LOW:HIGH seconds, LOW >= 0 (e.g. 0:0.01)",
            Quantity::MotorFilter => "LOW:HIGH hertz, LOW > 0 (e.g. 50:200)",
            Quantity::MotorNoload => "LOW:HIGH rad/s, LOW > 0 (e.g. 20:40)",
            Quantity::MotorLag => "LOW:HIGH seconds, LOW >= 0 (e.g. 0.004:0.01)",
        }
    }

    /// The modes that can apply it: noise, latency and the motor model act
    /// on the Rust PD, which servo mode (MuJoCo's own PD) does not have.
    pub fn supports(self, mode: Mode) -> bool {
        !self.rust_pd() || mode == Mode::Torque
    }

    /// True for what only the Rust PD of torque mode applies.
    pub fn rust_pd(self) -> bool {
        matches!(
            self,
            Quantity::QNoise
                | Quantity::Delay
                | Quantity::MotorDelay
                | Quantity::MotorFilter
                | Quantity::MotorNoload
                | Quantity::MotorLag
        )
    }
}

/// A distribution.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Dist {
    /// A factor uniform in [1 - f, 1 + f].
    Relative(f64),
    /// Uniform in [low, high].
    Uniform(f64, f64),
    /// Gaussian (mean, standard deviation).
    Normal(f64, f64),
    /// A whole number uniform in [low, high].
    Steps(u32, u32),
}

/// One `--randomize` spec.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Randomize {
    pub quantity: Quantity,
    pub dist: Dist,
}

fn bad(spec: &str, q: Option<Quantity>, why: &str) -> Error {
    let fix = match q {
        Some(q) => format!("write {}={}", q.name(), q.forms()),
        None => {
            let names: Vec<&str> = Quantity::ALL.iter().map(|q| q.name()).collect();
            format!("quantities are {}", names.join(", "))
        }
    };
    Error::Config(format!("--randomize '{spec}': {why}; {fix}"))
}

fn number(spec: &str, q: Quantity, t: &str) -> Result<f64> {
    t.trim()
        .parse::<f64>()
        .ok()
        .filter(|v| v.is_finite())
        .ok_or_else(|| {
            bad(
                spec,
                Some(q),
                &format!("'{}' is not a finite number", t.trim()),
            )
        })
}

/// `±P%`: a spread relative to the nominal value, under 100 %.
fn relative(spec: &str, q: Quantity, t: &str) -> Result<Dist> {
    let body = t
        .strip_prefix('±')
        .or_else(|| t.strip_prefix("+-"))
        .and_then(|r| r.strip_suffix('%'))
        .ok_or_else(|| bad(spec, Some(q), "not a relative spread"))?;
    let p = number(spec, q, body)?;
    if !(0.0..100.0).contains(&p) {
        return Err(bad(
            spec,
            Some(q),
            "the spread must be at least 0% and under 100%",
        ));
    }
    Ok(Dist::Relative(p / 100.0))
}

/// `N(MEAN,SIGMA)`: a Gaussian.
fn gaussian(spec: &str, q: Quantity, t: &str) -> Result<Dist> {
    let inner = t
        .strip_prefix("N(")
        .and_then(|r| r.strip_suffix(')'))
        .ok_or_else(|| bad(spec, Some(q), "not a Gaussian N(MEAN,SIGMA)"))?;
    let Some((m, s)) = inner.split_once(',') else {
        return Err(bad(spec, Some(q), "N() needs a mean and a sigma"));
    };
    let (m, s) = (number(spec, q, m)?, number(spec, q, s)?);
    if s < 0.0 {
        return Err(bad(spec, Some(q), "sigma is negative"));
    }
    Ok(Dist::Normal(m, s))
}

/// `LOW:HIGH` in whole steps.
fn steps(spec: &str, q: Quantity, t: &str) -> Result<Dist> {
    let (lo, hi) = t
        .split_once(':')
        .ok_or_else(|| bad(spec, Some(q), "not a range"))?;
    let whole = |v: &str| {
        v.trim().parse::<u32>().map_err(|_| {
            bad(
                spec,
                Some(q),
                &format!("'{}' is not a whole number >= 0", v.trim()),
            )
        })
    };
    let (lo, hi) = (whole(lo)?, whole(hi)?);
    if lo > hi {
        return Err(bad(spec, Some(q), "LOW is above HIGH"));
    }
    Ok(Dist::Steps(lo, hi))
}

/// `LOW:HIGH` drawn uniformly, inside what makes sense for the quantity.
fn uniform(spec: &str, q: Quantity, t: &str) -> Result<Dist> {
    let (lo, hi) = t
        .split_once(':')
        .ok_or_else(|| bad(spec, Some(q), "not a range"))?;
    let (lo, hi) = (number(spec, q, lo)?, number(spec, q, hi)?);
    if lo > hi {
        return Err(bad(spec, Some(q), "LOW is above HIGH"));
    }
    let positive = matches!(
        q,
        Quantity::Friction | Quantity::MotorFilter | Quantity::MotorNoload
    );
    let nonnegative = matches!(
        q,
        Quantity::PushAt | Quantity::MotorDelay | Quantity::MotorLag
    );
    if (positive && lo <= 0.0) || (nonnegative && lo < 0.0) {
        return Err(bad(
            spec,
            Some(q),
            "the range reaches values that make no sense",
        ));
    }
    // a lag past a servo's plausible one: most often milliseconds typed bare
    if q == Quantity::MotorLag
        && let Some((why, meant)) = crate::robot::model::servo_time_typo(hi)
    {
        let ms = match meant {
            Some(s) => format!(" (for {lo} to {hi} ms, motor_lag={}:{s})", lo / 1000.0),
            None => String::new(),
        };
        return Err(bad(spec, Some(q), &format!("HIGH {why}{ms}")));
    }
    Ok(Dist::Uniform(lo, hi))
}

impl Randomize {
    /// Parses `QUANTITY=DISTRIBUTION`.
    pub fn parse(spec: &str) -> Result<Randomize> {
        let Some((name, text)) = spec.split_once('=') else {
            return Err(bad(spec, None, "no '='"));
        };
        let key = name.trim().to_ascii_lowercase().replace('-', "_");
        let Some(&q) = Quantity::ALL.iter().find(|q| q.name() == key) else {
            return Err(bad(
                spec,
                None,
                &format!("unknown quantity '{}'", name.trim()),
            ));
        };
        let t = text.trim();
        let dist = match q {
            Quantity::TorsoMass | Quantity::LegMass | Quantity::MotorGain => relative(spec, q, t)?,
            Quantity::QNoise => gaussian(spec, q, t)?,
            Quantity::Delay => steps(spec, q, t)?,
            Quantity::Friction
            | Quantity::PushForce
            | Quantity::PushAt
            | Quantity::MotorDelay
            | Quantity::MotorFilter
            | Quantity::MotorNoload
            | Quantity::MotorLag => uniform(spec, q, t)?,
        };
        Ok(Randomize { quantity: q, dist })
    }

    /// Refuses a quantity the mode cannot apply.
    pub fn check_mode(&self, mode: Mode) -> Result<()> {
        if self.quantity.supports(mode) {
            return Ok(());
        }
        Err(Error::Config(format!(
            "--randomize {} needs --mode torque: it acts on {} of the Rust PD, and in {} mode MuJoCo computes the PD",
            self.quantity.name(),
            match self.quantity {
                Quantity::QNoise | Quantity::Delay => "the angles",
                _ => "the motor model",
            },
            mode.as_str()
        )))
    }
}

/// The generator of one draw: a function of its key alone.
fn generator(seed: u64, cell: &str, replicate: u32, q: Quantity, index: u32) -> ChaCha8Rng {
    let mut h = Sha256::new();
    h.update(b"pupper-randomize-v1\0");
    h.update(seed.to_le_bytes());
    h.update(cell.as_bytes());
    h.update([0u8]);
    h.update(replicate.to_le_bytes());
    h.update(q.name().as_bytes());
    h.update(index.to_le_bytes());
    let digest: [u8; 32] = h.finalize().into();
    ChaCha8Rng::from_seed(digest)
}

/// The `index`-th value (e.g. a joint) of `r` for a cell's replicate.
pub fn draw(r: &Randomize, seed: u64, cell: &str, replicate: u32, index: u32) -> f64 {
    let mut g = generator(seed, cell, replicate, r.quantity, index);
    // parsing guarantees these are valid; a degenerate one is its mean
    match r.dist {
        Dist::Relative(f) => {
            Uniform::new_inclusive(1.0 - f, 1.0 + f).map_or(1.0, |u| u.sample(&mut g))
        }
        Dist::Uniform(lo, hi) => Uniform::new_inclusive(lo, hi).map_or(lo, |u| u.sample(&mut g)),
        Dist::Normal(m, s) => Normal::new(m, s).map_or(m, |n| n.sample(&mut g)),
        Dist::Steps(lo, hi) => {
            Uniform::new_inclusive(lo, hi).map_or(lo, |u| u.sample(&mut g)) as f64
        }
    }
}

/// A sweep's population: how many replicates each cell runs, the seed, and
/// what varies between them. `count = 1` with nothing randomized is a plain
/// sweep (no replicates.csv; the manifest does not mention it).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Replicates {
    pub count: u32,
    pub seed: u64,
    #[serde(default)]
    pub randomize: Vec<Randomize>,
    /// Every cell's replicate r is the same robot (draws keyed without the
    /// cell id): common random numbers, so cells differ only by their
    /// settings and a comparison between them carries no draw noise.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub common_draws: bool,
}

impl Default for Replicates {
    fn default() -> Self {
        Replicates {
            count: 1,
            seed: 0,
            randomize: Vec::new(),
            common_draws: false,
        }
    }
}

/// What one replicate of one cell drew; quantities not randomized hold
/// their nominal value.
#[derive(Debug, Clone, PartialEq)]
pub struct Draws {
    /// Factor on the torso's mass and inertia.
    pub torso_mass: f64,
    /// Factor on the thigh and calf masses and inertias.
    pub leg_mass: f64,
    /// Factor on each actuator's gain, in actuator order; empty: all 1.
    pub motor_gain: Vec<f64>,
    /// Sliding friction of every colliding geom.
    pub friction: Option<f64>,
    /// The push's vertical force (N).
    pub push_force: Option<f64>,
    /// The push's start (s).
    pub push_at: Option<f64>,
    /// Control steps of observation latency (torque mode).
    pub delay: usize,
    /// The motor model's command delay (s), derivative filter (Hz),
    /// no-load speed (rad/s) and torque lag (s), where drawn (torque mode).
    pub motor_delay: Option<f64>,
    pub motor_filter: Option<f64>,
    pub motor_noload: Option<f64>,
    pub motor_lag: Option<f64>,
    /// Values in the order of [`Replicates::columns`].
    pub values: Vec<f64>,
}

/// Gaussian noise on the joint angles the torque-mode PD reads, one
/// stream per simulation (drawn in step order, actuator by actuator).
pub struct Noise {
    rng: ChaCha8Rng,
    normal: Normal<f64>,
}

impl Noise {
    pub fn sample(&mut self) -> f64 {
        self.normal.sample(&mut self.rng)
    }
}

impl Replicates {
    /// True for a plain sweep: one run per cell, nothing drawn.
    pub fn is_plain(&self) -> bool {
        self.count <= 1 && self.randomize.is_empty()
    }

    pub fn get(&self, q: Quantity) -> Option<&Randomize> {
        self.randomize.iter().find(|r| r.quantity == q)
    }

    /// Checks the population against the sweep it belongs to: the mode,
    /// whether there is a push, and the grid's axes.
    pub fn check(&self, mode: Mode, push: bool, axes: &[&str]) -> Result<()> {
        if self.count == 0 {
            return Err(Error::Config(
                "replicates is 0: give --replicates a whole number >= 1".into(),
            ));
        }
        for (i, r) in self.randomize.iter().enumerate() {
            let name = r.quantity.name();
            if self.randomize[..i].iter().any(|o| o.quantity == r.quantity) {
                return Err(Error::Config(format!(
                    "--randomize {name} is given twice: keep one"
                )));
            }
            r.check_mode(mode)?;
            if matches!(r.quantity, Quantity::PushForce | Quantity::PushAt) && !push {
                return Err(Error::Config(format!(
                    "--randomize {name} varies the push, and this run has none (--no-push, or `pupper lab`, whose disturbance is a sine): drop this --randomize, or run `pupper sweep` with a push"
                )));
            }
            if matches!(r.quantity, Quantity::Friction | Quantity::PushForce)
                && axes.contains(&name)
            {
                return Err(Error::Config(format!(
                    "both the grid and --randomize set {name}: drop the {name} axis or the --randomize"
                )));
            }
        }
        Ok(())
    }

    /// The drawn-value columns of replicates.csv, in spec order
    /// (`motor_gain` has one per actuator; `q_noise` none: it is drawn
    /// every step).
    pub fn columns(&self, nu: usize) -> Vec<String> {
        let mut out = Vec::new();
        for r in &self.randomize {
            match r.quantity {
                Quantity::MotorGain => {
                    out.extend((0..nu).map(|a| format!("motor_gain_{a}")));
                }
                Quantity::QNoise => {}
                q => out.push(q.name().to_string()),
            }
        }
        out
    }

    /// Replicate `replicate` of the cell `cell_id`, for a model of `nu`
    /// actuators.
    pub fn draws(&self, cell_id: &str, replicate: u32, nu: usize) -> Draws {
        let cell_id = self.key(cell_id);
        let mut d = Draws {
            torso_mass: 1.0,
            leg_mass: 1.0,
            motor_gain: Vec::new(),
            friction: None,
            push_force: None,
            push_at: None,
            delay: 0,
            motor_delay: None,
            motor_filter: None,
            motor_noload: None,
            motor_lag: None,
            values: Vec::new(),
        };
        let one = |r: &Randomize| draw(r, self.seed, cell_id, replicate, 0);
        for r in &self.randomize {
            match r.quantity {
                Quantity::MotorGain => {
                    d.motor_gain = (0..nu)
                        .map(|a| draw(r, self.seed, cell_id, replicate, a as u32))
                        .collect();
                    d.values.extend(&d.motor_gain);
                    continue;
                }
                Quantity::QNoise => continue,
                _ => {}
            }
            let v = one(r);
            match r.quantity {
                Quantity::TorsoMass => d.torso_mass = v,
                Quantity::LegMass => d.leg_mass = v,
                Quantity::Friction => d.friction = Some(v),
                Quantity::PushForce => d.push_force = Some(v),
                Quantity::PushAt => d.push_at = Some(v),
                Quantity::Delay => d.delay = v as usize,
                Quantity::MotorDelay => d.motor_delay = Some(v),
                Quantity::MotorFilter => d.motor_filter = Some(v),
                Quantity::MotorNoload => d.motor_noload = Some(v),
                Quantity::MotorLag => d.motor_lag = Some(v),
                Quantity::MotorGain | Quantity::QNoise => {}
            }
            d.values.push(v);
        }
        d
    }

    /// What a cell's draws are keyed by: its id, or nothing with common draws.
    fn key<'a>(&self, cell_id: &'a str) -> &'a str {
        if self.common_draws { "" } else { cell_id }
    }

    /// The angle-noise stream of a replicate, when `q_noise` is randomized.
    pub fn noise(&self, cell_id: &str, replicate: u32) -> Option<Noise> {
        let r = self.get(Quantity::QNoise)?;
        let Dist::Normal(m, s) = r.dist else {
            return None;
        };
        let normal = Normal::new(m, s).ok()?;
        Some(Noise {
            rng: generator(self.seed, self.key(cell_id), replicate, Quantity::QNoise, 0),
            normal,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p(s: &str) -> Randomize {
        Randomize::parse(s).unwrap()
    }

    #[test]
    fn specs_parse_to_their_distributions() {
        assert_eq!(p("torso_mass=±10%").dist, Dist::Relative(0.1));
        assert_eq!(p("motor_gain=+-5%").dist, Dist::Relative(0.05));
        assert_eq!(p("friction=0.5:1.2").dist, Dist::Uniform(0.5, 1.2));
        assert_eq!(p("push_force=-35:-15").dist, Dist::Uniform(-35.0, -15.0));
        assert_eq!(p("q_noise=N(0,0.002)").dist, Dist::Normal(0.0, 0.002));
        assert_eq!(p("delay=0:3").dist, Dist::Steps(0, 3));
        assert_eq!(p("motor_lag=0:0.01").dist, Dist::Uniform(0.0, 0.01));
        assert_eq!(p("Leg-Mass=±10%").quantity, Quantity::LegMass);
    }

    #[test]
    fn bad_specs_say_what_to_write() {
        let e = |s: &str| Randomize::parse(s).unwrap_err().to_string();
        assert!(
            e("friction=±").contains("friction=LOW:HIGH"),
            "{}",
            e("friction=±")
        );
        assert!(e("torso_mass=abc").contains("±P%"));
        assert!(e("friction=-1:2").contains("make no sense"));
        assert!(e("motor_lag=-0.001:0.01").contains("make no sense"));
        assert!(
            e("motor_lag=0:10").contains("motor_lag=0:0.01"),
            "{}",
            e("motor_lag=0:10")
        );
        assert!(e("push_at=3:1").contains("LOW is above HIGH"));
        assert!(e("delay=0:-1").contains("whole number"));
        assert!(
            e("wind=1:2").contains("unknown quantity 'wind'") && e("wind=1:2").contains("q_noise")
        );
        assert!(e("q_noise=N(0,-1)").contains("negative"));
        assert!(e("torso_mass=±120%").contains("under 100%"));
        let servo = p("delay=0:2")
            .check_mode(Mode::Servo)
            .unwrap_err()
            .to_string();
        assert!(servo.contains("--mode torque"), "{servo}");
        assert!(p("friction=0.5:1").check_mode(Mode::Servo).is_ok());
    }

    #[test]
    fn draws_depend_on_their_key_only() {
        let r = p("friction=0.5:1.2");
        let a = draw(&r, 7, "kp30_kd1", 3, 0);
        assert_eq!(a, draw(&r, 7, "kp30_kd1", 3, 0));
        assert!((0.5..=1.2).contains(&a));
        assert_ne!(a, draw(&r, 8, "kp30_kd1", 3, 0), "another seed");
        assert_ne!(a, draw(&r, 7, "kp30_kd1", 4, 0), "another replicate");
        assert_ne!(a, draw(&r, 7, "kp60_kd1", 3, 0), "another cell");
        assert_ne!(a, draw(&r, 7, "kp30_kd1", 3, 1), "another index");
        let t = p("torso_mass=±10%");
        assert_ne!(draw(&t, 7, "kp30_kd1", 3, 0), draw(&r, 7, "kp30_kd1", 3, 0));
    }

    #[test]
    fn a_population_is_checked_against_its_sweep() {
        let pop = |specs: &[&str], count| Replicates {
            count,
            seed: 1,
            randomize: specs.iter().map(|s| p(s)).collect(),
            common_draws: false,
        };
        let e = |r: Replicates, mode, push, axes: &[&str]| {
            r.check(mode, push, axes).unwrap_err().to_string()
        };
        assert!(e(pop(&[], 0), Mode::Torque, true, &[]).contains("--replicates"));
        assert!(e(pop(&["delay=0:1", "delay=1:2"], 4), Mode::Torque, true, &[]).contains("twice"));
        assert!(e(pop(&["push_at=1:2"], 4), Mode::Torque, false, &[]).contains("--no-push"));
        assert!(
            e(
                pop(&["friction=0.5:1"], 4),
                Mode::Servo,
                true,
                &["kp", "friction"]
            )
            .contains("drop the friction axis")
        );
        assert!(
            e(pop(&["q_noise=N(0,0.01)"], 4), Mode::Servo, true, &[]).contains("--mode torque")
        );
        assert!(
            pop(&["torso_mass=±10%"], 4)
                .check(Mode::Servo, true, &["torso_mass_scale"])
                .is_ok()
        );
        assert!(pop(&[], 1).is_plain() && !pop(&[], 2).is_plain());
        assert!(!pop(&["friction=1:1"], 1).is_plain());
    }

    #[test]
    fn draws_fill_their_columns_in_spec_order() {
        let r = Replicates {
            count: 4,
            seed: 3,
            randomize: [
                "delay=0:3",
                "motor_gain=±5%",
                "q_noise=N(0,0.1)",
                "torso_mass=±10%",
            ]
            .iter()
            .map(|s| p(s))
            .collect(),
            common_draws: false,
        };
        assert_eq!(
            r.columns(2),
            ["delay", "motor_gain_0", "motor_gain_1", "torso_mass"]
        );
        let d = r.draws("kp30", 2, 2);
        assert_eq!(d.values.len(), 4);
        assert_eq!(d.values[0], d.delay as f64);
        assert_eq!(d.values[1..3], d.motor_gain[..]);
        assert_eq!(d.values[3], d.torso_mass);
        assert_eq!((d.leg_mass, d.friction, d.push_at), (1.0, None, None));
        assert!(d.motor_gain.iter().all(|g| (0.95..=1.05).contains(g)));
        assert_ne!(d.motor_gain[0], d.motor_gain[1], "drawn per actuator");
        // the noise stream is a function of its key: two readers agree
        let (mut a, mut b) = (r.noise("kp30", 2).unwrap(), r.noise("kp30", 2).unwrap());
        let xs: Vec<f64> = (0..5).map(|_| a.sample()).collect();
        assert_eq!(xs, (0..5).map(|_| b.sample()).collect::<Vec<_>>());
        assert!(r.noise("kp30", 3).unwrap().sample() != xs[0]);
        // nothing randomized: the nominal robot
        let plain = Replicates::default().draws("kp30", 0, 12);
        assert_eq!((plain.torso_mass, plain.delay), (1.0, 0));
        assert!(plain.values.is_empty() && plain.motor_gain.is_empty());
        assert!(Replicates::default().noise("kp30", 0).is_none());
    }

    #[test]
    fn common_draws_give_every_cell_the_same_robots() {
        let mut r = Replicates {
            count: 2,
            seed: 5,
            randomize: ["torso_mass=±10%", "q_noise=N(0,0.1)"]
                .iter()
                .map(|s| p(s))
                .collect(),
            common_draws: false,
        };
        assert_ne!(r.draws("kp30", 1, 2), r.draws("kp60", 1, 2));
        r.common_draws = true;
        assert_eq!(r.draws("kp30", 1, 2), r.draws("kp60", 1, 2));
        assert_ne!(r.draws("kp30", 0, 2), r.draws("kp30", 1, 2));
        let (mut a, mut b) = (r.noise("kp30", 1).unwrap(), r.noise("kp60", 1).unwrap());
        assert_eq!(a.sample(), b.sample());
    }

    /// Mean and spread of 20 000 draws against the spec, with a fixed seed;
    /// tolerances are five standard errors.
    #[test]
    fn draws_follow_their_distributions() {
        let n = 20_000u32;
        let stats = |r: &Randomize| {
            let xs: Vec<f64> = (0..n).map(|i| draw(r, 1, "cell", i, 0)).collect();
            let m = xs.iter().sum::<f64>() / n as f64;
            let v = xs.iter().map(|x| (x - m).powi(2)).sum::<f64>() / n as f64;
            (m, v.sqrt(), xs)
        };
        // uniform [a, b]: mean (a+b)/2, sd (b-a)/sqrt(12)
        let (m, s, xs) = stats(&p("friction=0.5:1.2"));
        let sd = 0.7 / 12f64.sqrt();
        assert!((m - 0.85).abs() < 5.0 * sd / (n as f64).sqrt(), "{m}");
        assert!((s - sd).abs() < 0.01, "{s}");
        assert!(xs.iter().all(|x| (0.5..=1.2).contains(x)));
        let (m, s, _) = stats(&p("torso_mass=±10%"));
        assert!(
            (m - 1.0).abs() < 5.0 * (0.2 / 12f64.sqrt()) / (n as f64).sqrt(),
            "{m}"
        );
        assert!((s - 0.2 / 12f64.sqrt()).abs() < 0.003, "{s}");
        let (m, s, _) = stats(&p("q_noise=N(0,0.002)"));
        assert!(m.abs() < 5.0 * 0.002 / (n as f64).sqrt(), "{m}");
        assert!((s - 0.002).abs() < 0.0001, "{s}");
        let (m, _, xs) = stats(&p("delay=0:3"));
        assert!((m - 1.5).abs() < 0.05, "{m}");
        for k in 0..=3 {
            let share = xs.iter().filter(|&&x| x == k as f64).count() as f64 / n as f64;
            assert!((share - 0.25).abs() < 0.02, "{k}: {share}");
        }
    }
}

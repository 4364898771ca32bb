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
use crate::physics::Mode;

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
}

impl Quantity {
    pub const ALL: [Quantity; 8] = [
        Quantity::TorsoMass,
        Quantity::LegMass,
        Quantity::MotorGain,
        Quantity::Friction,
        Quantity::PushForce,
        Quantity::PushAt,
        Quantity::QNoise,
        Quantity::Delay,
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
        }
    }

    /// The modes that can apply it: noise and latency act on what the Rust
    /// PD reads, which servo mode (MuJoCo's own PD) does not have.
    pub fn supports(self, mode: Mode) -> bool {
        !matches!(self, Quantity::QNoise | Quantity::Delay) || mode == Mode::Torque
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
            Quantity::TorsoMass | Quantity::LegMass | Quantity::MotorGain => {
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
                Dist::Relative(p / 100.0)
            }
            Quantity::QNoise => {
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
                Dist::Normal(m, s)
            }
            Quantity::Delay => {
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
                Dist::Steps(lo, hi)
            }
            Quantity::Friction | Quantity::PushForce | Quantity::PushAt => {
                let (lo, hi) = t
                    .split_once(':')
                    .ok_or_else(|| bad(spec, Some(q), "not a range"))?;
                let (lo, hi) = (number(spec, q, lo)?, number(spec, q, hi)?);
                if lo > hi {
                    return Err(bad(spec, Some(q), "LOW is above HIGH"));
                }
                if (q == Quantity::Friction && lo <= 0.0) || (q == Quantity::PushAt && lo < 0.0) {
                    return Err(bad(
                        spec,
                        Some(q),
                        "the range reaches values that make no sense",
                    ));
                }
                Dist::Uniform(lo, hi)
            }
        };
        Ok(Randomize { quantity: q, dist })
    }

    /// Refuses a quantity the mode cannot apply.
    pub fn check_mode(&self, mode: Mode) -> Result<()> {
        if self.quantity.supports(mode) {
            return Ok(());
        }
        Err(Error::Config(format!(
            "--randomize {} needs --mode torque: it acts on the angles the Rust PD reads, and in {} mode MuJoCo computes the PD",
            self.quantity.name(),
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

//! Which implementation steps the physics: MuJoCo's C library on the CPU
//! threads (float64), or MuJoCo Warp (float32) on a CUDA device or the CPU.
//! It decides numbers (precision), so it is part of the sweep's config and a
//! resume must match it; a CPU run's manifest leaves it out.

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::plan::mode::Mode;
use crate::plan::randomize::{Quantity, Replicates};

#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(tag = "name", rename_all = "snake_case")]
pub enum Backend {
    /// `mujoco.batch` on MuJoCo's thread pool, float64.
    #[default]
    Cpu,
    /// MuJoCo Warp: every simulation of a batch a world of one device
    /// model, float32.
    Warp {
        /// A Warp device: `cuda`, `cuda:N` or `cpu`.
        device: String,
        #[serde(default = "float32")]
        precision: String,
    },
}

fn float32() -> String {
    "float32".into()
}

/// The device `--backend warp` uses when none is given.
pub const DEFAULT_WARP_DEVICE: &str = "cuda:0";

impl Backend {
    pub fn is_cpu(&self) -> bool {
        matches!(self, Backend::Cpu)
    }

    /// `--backend NAME [--device DEVICE]`.
    pub fn parse(name: &str, device: Option<&str>) -> Result<Backend> {
        match (name, device) {
            ("cpu", None) => Ok(Backend::Cpu),
            ("cpu", Some(d)) => Err(Error::Config(format!(
                "--device {d} is for --backend warp; the cpu backend runs on this machine's cores (set --threads): drop --device or add --backend warp"
            ))),
            ("warp", d) => Ok(Backend::Warp {
                device: parse_device(d.unwrap_or(DEFAULT_WARP_DEVICE))?,
                precision: float32(),
            }),
            _ => Err(Error::Config(format!(
                "backend '{name}' is unknown: use 'cpu' (MuJoCo on the CPU cores) or 'warp' (MuJoCo Warp on a GPU)"
            ))),
        }
    }

    pub fn name(&self) -> &'static str {
        match self {
            Backend::Cpu => "cpu",
            Backend::Warp { .. } => "warp",
        }
    }

    /// Floating-point precision of the physics.
    pub fn precision(&self) -> &str {
        match self {
            Backend::Cpu => "float64",
            Backend::Warp { precision, .. } => precision,
        }
    }

    /// Refuses what this backend cannot run. Warp runs torque mode's PD as
    /// actuator parameters (gain, affine bias, force clip) inside the step,
    /// so what needs the PD in Rust every step is refused there.
    pub fn check(&self, mode: Mode, replicates: &Replicates) -> Result<()> {
        if self.is_cpu() || mode != Mode::Torque {
            return Ok(());
        }
        for r in &replicates.randomize {
            if r.quantity.rust_pd() || r.quantity == Quantity::MotorGain {
                return Err(Error::Config(format!(
                    "--randomize {} in torque mode needs the Rust PD of --backend cpu: the warp backend runs the PD inside MuJoCo's actuators; use --backend cpu",
                    r.quantity.name()
                )));
            }
        }
        Ok(())
    }
}

/// `cpu`, `cuda` or `cuda:N`, as Warp names devices.
fn parse_device(text: &str) -> Result<String> {
    let ok = match text.strip_prefix("cuda:") {
        Some(n) => !n.is_empty() && n.bytes().all(|b| b.is_ascii_digit()),
        None => text == "cpu" || text == "cuda",
    };
    if ok {
        Ok(text.to_string())
    } else {
        Err(Error::Config(format!(
            "device '{text}' is not a Warp device: use cuda:0 (a GPU; cuda:1 the second) or cpu (slow, for tests)"
        )))
    }
}

/// The PD law `tau = clip(kp (q* - q) - kd qdot, ±max)` as MuJoCo actuator
/// parameters: fixed gain `kp`, affine bias `(0, -kp, -kd)`, control `q*`,
/// force range `±max`. MuJoCo then computes `kp q* + 0 - kp q - kd qdot`
/// and clips it, so torque mode needs no per-step host round trip.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ActuatorPd {
    pub gain: f64,
    pub bias: [f64; 3],
    pub ctrl: f64,
    pub force_range: [f64; 2],
}

impl ActuatorPd {
    pub fn new(kp: f64, kd: f64, target: f64, max: f64) -> ActuatorPd {
        ActuatorPd {
            gain: kp,
            bias: [0.0, -kp, -kd],
            ctrl: target,
            force_range: [-max, max],
        }
    }

    /// The force MuJoCo's affine actuator produces at `(q, qdot)`.
    pub fn force(&self, q: f64, qdot: f64) -> f64 {
        let raw = self.gain * self.ctrl + self.bias[0] + self.bias[1] * q + self.bias[2] * qdot;
        raw.clamp(self.force_range[0], self.force_range[1])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::pd;
    use rand_chacha::ChaCha8Rng;
    use rand_chacha::rand_core::SeedableRng;
    use rand_distr::{Distribution, Uniform};

    #[test]
    fn parses_names_and_devices() {
        assert_eq!(Backend::parse("cpu", None).unwrap(), Backend::Cpu);
        let w = Backend::parse("warp", None).unwrap();
        assert_eq!(
            w,
            Backend::Warp {
                device: "cuda:0".into(),
                precision: "float32".into()
            }
        );
        assert_eq!(w.precision(), "float32");
        for d in ["cpu", "cuda", "cuda:3"] {
            assert!(Backend::parse("warp", Some(d)).is_ok(), "{d}");
        }
        for d in ["gpu", "cuda:", "cuda:x", ""] {
            let e = Backend::parse("warp", Some(d)).unwrap_err().to_string();
            assert!(e.contains("cuda:0"), "{e}");
        }
        assert!(Backend::parse("jax", None).is_err());
        assert!(
            Backend::parse("cpu", Some("cuda:0"))
                .unwrap_err()
                .to_string()
                .contains("--backend warp")
        );
    }

    #[test]
    fn manifest_form() {
        let w = Backend::parse("warp", Some("cpu")).unwrap();
        let j = serde_json::to_string(&w).unwrap();
        assert_eq!(j, r#"{"name":"warp","device":"cpu","precision":"float32"}"#);
        assert_eq!(serde_json::from_str::<Backend>(&j).unwrap(), w);
    }

    #[test]
    fn actuator_mapping_is_the_rust_pd() {
        // known answer: 10 (0.5 - 0.2) - 2 * 0.1 = 2.8, inside ±3
        let a = ActuatorPd::new(10.0, 2.0, 0.5, 3.0);
        assert!((a.force(0.2, 0.1) - 2.8).abs() < 1e-12);
        assert_eq!(ActuatorPd::new(100.0, 0.0, 1.0, 3.0).force(0.0, 0.0), 3.0);
        let mut g = ChaCha8Rng::seed_from_u64(5);
        let mut u = |lo: f64, hi: f64| Uniform::new(lo, hi).unwrap().sample(&mut g);
        for _ in 0..100_000 {
            let (kp, kd, target) = (u(0.0, 200.0), u(0.0, 10.0), u(-2.0, 2.0));
            let (q, v, max) = (u(-3.0, 3.0), u(-50.0, 50.0), u(0.1, 5.0));
            let (tau, _) = pd::torque(kp, kd, target, q, v, max);
            let f = ActuatorPd::new(kp, kd, target, max).force(q, v);
            // the same law; only the rounding of kp q* - kp q vs kp (q* - q)
            assert!((tau - f).abs() <= 1e-12 * (1.0 + kp * 4.0), "{tau} {f}");
        }
    }
}

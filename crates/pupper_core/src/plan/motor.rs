//! `--motor SPEC`: the servo firmware and motor that torque mode's PD runs
//! through, like the hardware's (see [`crate::math::motor`]). The default,
//! ideal motor computes the PD every physics step on the exact state and
//! delivers it up to the torque limit: today's torque mode, byte for byte.

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};

/// The keys of `--motor`, with what each means, for help and errors.
pub const KEYS: [(&str, &str); 6] = [
    (
        "rate",
        "the firmware's PD rate (Hz), torque held between updates",
    ),
    ("filter", "a first-order low-pass on the derivative (Hz)"),
    (
        "counts",
        "encoder counts per revolution (the angle is quantised)",
    ),
    ("delay", "command delay (s): the target arrives this late"),
    (
        "noload",
        "no-load speed (rad/s): the torque limit falls linearly to 0 there",
    ),
    (
        "lag",
        "the torque's first-order lag behind the PD (s, at most 0.05; 0: none): a current loop's",
    ),
];

/// The servo's firmware and motor. Every field None (delay 0) is the
/// ideal motor, which a manifest leaves out.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Motor {
    /// The PD's update rate (Hz); None: every physics step.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rate: Option<f64>,
    /// Cutoff (Hz) of the low-pass filter on the derivative; None: none.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub filter: Option<f64>,
    /// Encoder counts per revolution; None: the exact angle. With it, the
    /// derivative is the encoder's difference over an update period.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub counts: Option<u32>,
    /// Command delay (s): the PD tracks the target of this long ago.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub delay: f64,
    /// No-load speed (rad/s); None: the torque limit at every speed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub noload: Option<f64>,
    /// Time constant (s) of the torque's first-order lag behind the PD (a
    /// current loop's, as `pupper fit` measures it); None: none.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lag: Option<f64>,
}

fn is_zero(v: &f64) -> bool {
    *v == 0.0
}

/// The feedback path a firmware spec (`--motor`) and a sensing delay ask
/// for, at physics step `dt`; None when neither is given (no margins).
pub fn feedback_of(
    motor: Option<&str>,
    sensing: Option<f64>,
    dt: f64,
) -> Result<Option<crate::math::margins::Feedback>> {
    if motor.is_none() && sensing.is_none() {
        return Ok(None);
    }
    let sensing = sensing.unwrap_or(0.0);
    if !(sensing.is_finite() && sensing >= 0.0) {
        return Err(Error::Config(format!(
            "--sensing-delay {sensing} must be a number of seconds >= 0"
        )));
    }
    // as a torque lag: past what a servo's latency can be (the bound a fit
    // fits it within) is most often milliseconds typed bare
    if let Some((_, meant)) = crate::robot::model::servo_time_typo(sensing) {
        let fix = meant.map_or("e.g. --sensing-delay 0.002 for 2 ms".into(), |s| {
            format!("for {sensing} ms give --sensing-delay {s}")
        });
        return Err(Error::Config(format!(
            "--sensing-delay {sensing}: {sensing} s is past the {} s a servo's feedback latency can be (the bound `pupper fit` fits it within); it is in seconds: {fix}",
            crate::robot::model::MAX_SERVO_TIME
        )));
    }
    Ok(Some(
        Motor::parse(motor.unwrap_or(""))?.feedback(sensing, dt),
    ))
}

/// The feedback path of one actuator's loop on a calibrated model (the
/// sampled loop where its PD acts every step: [`Motor::sampled_feedback`]):
/// the firmware `motor` with the actuator's fitted torque `lag` where
/// `motor` sets none, and its fitted feedback `latency` where no `sensing`
/// delay is given (a user's `--motor lag=` or `--sensing-delay` stands
/// instead), the latency read as torque mode's firmware reads it
/// ([`Motor::late_steps`]).
pub fn fitted_feedback(
    motor: &Motor,
    sensing: Option<f64>,
    dt: f64,
    lag: f64,
    latency: f64,
) -> crate::math::margins::Feedback {
    let mut m = motor.clone();
    if m.lag.is_none() && lag > 0.0 {
        m.lag = Some(lag);
    }
    let late = match sensing {
        Some(s) => s / dt,
        None => m.late_steps(latency, dt),
    };
    m.sampled_feedback(late, dt)
}

/// How much later (physics steps) a PD updated every step and held over
/// it acts than a continuous one: a quarter step under MuJoCo's
/// semi-implicit Euler, which moves the angle by a held torque's whole step
/// at once. A fitted latency is what `pupper fit`'s replay found beyond a
/// continuous PD, so a firmware without a rate of its own reads that much
/// younger (the fit's replay and torque mode alike).
pub const HELD_STEPS: f64 = 0.25;

impl Motor {
    /// How many physics steps of `dt` old the state is that a PD with a
    /// fitted feedback `latency` (s) reads: a firmware without a rate of
    /// its own reads [`HELD_STEPS`] younger; none below 0.
    pub fn late_steps(&self, latency: f64, dt: f64) -> f64 {
        if latency <= 0.0 {
            return 0.0;
        }
        let held = if self.rate.is_none() { HELD_STEPS } else { 0.0 };
        (latency / dt - held).max(0.0)
    }

    /// Whether the PD updates every physics step of `dt`.
    pub fn every_step(&self, dt: f64) -> bool {
        self.rate.is_none_or(|r| r * dt >= 1.0 - 1e-9)
    }

    /// What this firmware puts in a joint's feedback path, measurements
    /// `sensing` s old, the physics stepping at `dt`: the sensing delay
    /// plus half an update period (the PD's output is held for one: `rate`,
    /// else every step), the derivative's filter, and half a period more on
    /// the derivative when it is an encoder's difference over a period.
    /// The continuous loop: on a model no fit calibrated, a conservative
    /// stand-in for hardware that the simulation's step discretises
    /// coarsely. The command delay is not feedback: it moves the target,
    /// not the loop.
    pub fn feedback(&self, sensing: f64, dt: f64) -> crate::math::margins::Feedback {
        let period = self.period(dt);
        crate::math::margins::Feedback {
            latency: sensing + 0.5 * period,
            filter_hz: self.filter,
            derivative_delay: if self.counts.is_some() {
                0.5 * period
            } else {
                0.0
            },
            torque_lag: self.lag.unwrap_or(0.0),
            hold: 0.5 * period,
            sampled: None,
        }
    }

    /// The feedback path of a calibrated servo (`pupper fit` identified it
    /// through the simulation, whose loop it then is): a PD that acts every
    /// physics step closes the sampled loop the simulation steps
    /// ([`crate::math::margins::Sampled`]), its state `late` steps old and
    /// the encoder's difference over a step the very velocity semi-implicit
    /// Euler steps with; a slower one, the continuous loop of
    /// [`Motor::feedback`].
    pub fn sampled_feedback(&self, late: f64, dt: f64) -> crate::math::margins::Feedback {
        let mut fb = self.feedback(late * dt, dt);
        if self.every_step(dt) {
            fb.derivative_delay = 0.0;
            fb.sampled = Some(crate::math::margins::Sampled { step: dt, late });
        }
        fb
    }

    pub fn is_ideal(&self) -> bool {
        *self == Motor::default()
    }

    /// `rate=1000,filter=200,counts=16384,delay=0.004,noload=30,lag=0.007`, any
    /// subset in any order; `ideal` or empty: the ideal motor.
    pub fn parse(text: &str) -> Result<Motor> {
        let mut m = Motor::default();
        let text = text.trim();
        if text.is_empty() || text == "ideal" {
            return Ok(m);
        }
        let mut seen: Vec<&str> = Vec::new();
        for part in text.split(',') {
            let part = part.trim();
            let Some((key, value)) = part.split_once('=') else {
                return Err(bad(format!(
                    "--motor item '{part}' is not KEY=VALUE: write e.g. rate=1000,filter=200 (keys: {})",
                    key_list()
                )));
            };
            let (key, value) = (key.trim(), value.trim());
            if !KEYS.iter().any(|(k, _)| *k == key) {
                let hint = KEYS
                    .iter()
                    .map(|(k, _)| *k)
                    .find(|k| strsim::jaro_winkler(k, key) > 0.8)
                    .map(|k| format!("did you mean '{k}'? "))
                    .unwrap_or_default();
                return Err(bad(format!(
                    "--motor key '{key}' is unknown: {hint}keys are {}",
                    key_list()
                )));
            }
            if seen.contains(&key) {
                return Err(bad(format!("--motor gives '{key}' twice: keep one value")));
            }
            seen.push(key);
            let number = |positive: bool| -> Result<f64> {
                let v: f64 = value.parse().map_err(|_| {
                    bad(format!(
                        "--motor {key}={value} is not a number: give e.g. {key}={}",
                        example(key)
                    ))
                })?;
                let ok = v.is_finite() && if positive { v > 0.0 } else { v >= 0.0 };
                if !ok {
                    return Err(bad(format!(
                        "--motor {key}={value} must be {} and finite: give e.g. {key}={}",
                        if positive { "> 0" } else { ">= 0" },
                        example(key)
                    )));
                }
                Ok(v)
            };
            match key {
                "rate" => m.rate = Some(number(true)?),
                "filter" => m.filter = Some(number(true)?),
                "delay" => m.delay = number(false)?,
                "noload" => m.noload = Some(number(true)?),
                "lag" => {
                    // 0 is no lag (a fitted 0 pasted back); past a servo's
                    // plausible lag is most often milliseconds typed bare
                    let v = number(false)?;
                    if let Some((why, meant)) = crate::robot::model::servo_time_typo(v) {
                        let fix = meant.map_or("e.g. lag=0.007 for 7 ms".into(), |s| {
                            format!("for {v} ms write lag={s}")
                        });
                        return Err(bad(format!("--motor lag={value}: {why}: {fix}")));
                    }
                    m.lag = Some(v).filter(|&l| l > 0.0);
                }
                _ => {
                    m.counts = Some(match value.parse::<u32>() {
                        Ok(c) if c >= 2 => c,
                        _ => {
                            return Err(bad(format!(
                                "--motor counts={value} is not a whole number of counts >= 2: give e.g. counts=16384"
                            )));
                        }
                    })
                }
            }
        }
        Ok(m)
    }

    /// Refuses a firmware faster than the physics it runs in.
    pub fn check_timestep(&self, dt: f64) -> Result<()> {
        match self.rate {
            Some(r) if r * dt > 1.0 + 1e-9 => Err(bad(format!(
                "--motor rate={r} Hz is faster than the physics ({:.6} Hz at timestep {dt} s): give a rate at or below it, or a smaller timestep",
                1.0 / dt
            ))),
            _ => Ok(()),
        }
    }

    /// The PD's update period on a physics step `dt`.
    pub fn period(&self, dt: f64) -> f64 {
        self.rate.map_or(dt, |r| 1.0 / r)
    }

    /// As `--motor` takes it (empty for the ideal motor).
    pub fn spec(&self) -> String {
        let mut parts = Vec::new();
        if let Some(r) = self.rate {
            parts.push(format!("rate={r}"));
        }
        if let Some(f) = self.filter {
            parts.push(format!("filter={f}"));
        }
        if let Some(c) = self.counts {
            parts.push(format!("counts={c}"));
        }
        if self.delay != 0.0 {
            parts.push(format!("delay={}", self.delay));
        }
        if let Some(w) = self.noload {
            parts.push(format!("noload={w}"));
        }
        if let Some(l) = self.lag {
            parts.push(format!("lag={l}"));
        }
        parts.join(",")
    }
}

fn bad(text: String) -> Error {
    Error::Config(text)
}

fn key_list() -> String {
    KEYS.iter().map(|(k, _)| *k).collect::<Vec<_>>().join(", ")
}

fn example(key: &str) -> &'static str {
    match key {
        "rate" => "1000",
        "filter" => "200",
        "delay" => "0.004",
        "lag" => "0.007",
        _ => "30",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_every_key_and_round_trips() {
        let m = Motor::parse("rate=1000, filter=200,counts=16384,delay=0.004,noload=30,lag=0.007")
            .unwrap();
        assert_eq!(m.rate, Some(1000.0));
        assert_eq!(m.filter, Some(200.0));
        assert_eq!(m.counts, Some(16384));
        assert_eq!(m.delay, 0.004);
        assert_eq!(m.noload, Some(30.0));
        assert_eq!(m.lag, Some(0.007));
        assert_eq!(m.feedback(0.0, 0.002).torque_lag, 0.007);
        assert!(!m.is_ideal());
        assert_eq!(Motor::parse(&m.spec()).unwrap(), m);
        assert!(Motor::parse("ideal").unwrap().is_ideal());
        assert!(Motor::parse("").unwrap().is_ideal());
        // the ideal motor is absent from a manifest
        assert_eq!(serde_json::to_string(&Motor::default()).unwrap(), "{}");
        let j = serde_json::to_string(&m).unwrap();
        assert_eq!(serde_json::from_str::<Motor>(&j).unwrap(), m);
        assert_eq!(m.period(0.002), 0.001);
        assert_eq!(Motor::default().period(0.002), 0.002);
    }

    #[test]
    fn bad_specs_get_one_line_with_the_fix() {
        let e = |s: &str| Motor::parse(s).unwrap_err().to_string();
        assert!(
            e("rat=100").contains("did you mean 'rate'"),
            "{}",
            e("rat=100")
        );
        assert!(e("rate").contains("KEY=VALUE"));
        assert!(e("rate=0").contains("> 0"));
        assert!(e("delay=-1").contains(">= 0"));
        assert!(e("filter=abc").contains("not a number"));
        assert!(e("counts=1").contains(">= 2"));
        assert!(e("counts=2.5").contains("whole number"));
        // 0 is no lag (a fitted 0 pasted back); 10 is 10 ms typed bare
        assert!(Motor::parse("lag=0").unwrap().is_ideal());
        assert!(e("lag=10").contains("write lag=0.01"), "{}", e("lag=10"));
        let sensing = |v: f64| feedback_of(None, Some(v), 0.002).unwrap_err().to_string();
        assert!(
            sensing(2.0).contains("for 2 ms give --sensing-delay 0.002"),
            "{}",
            sensing(2.0)
        );
        assert!(feedback_of(None, Some(0.05), 0.002).is_ok());
        // a reading to the nanosecond, and none where milliseconds make no servo
        assert!(
            e("lag=7.3").contains("for 7.3 ms write lag=0.0073:")
                || e("lag=7.3").ends_with("lag=0.0073"),
            "{}",
            e("lag=7.3")
        );
        assert!(
            e("lag=0.06").contains("e.g. lag=0.007 for 7 ms") && !e("lag=0.06").contains("0.0000"),
            "{}",
            e("lag=0.06")
        );
        assert!(e("rate=1,rate=2").contains("twice"));
        assert!(!e("wind=3").contains('\n'));
        let m = Motor::parse("rate=1000").unwrap();
        assert!(m.check_timestep(0.001).is_ok());
        assert!(
            m.check_timestep(0.002)
                .unwrap_err()
                .to_string()
                .contains("faster than the physics")
        );
    }
}

//! Recorded states for drawing: qpos at a fixed frame rate, taken from the
//! same simulation that produces the metrics, so a picture shows exactly
//! what was measured.

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};

/// The states of one cell at `fps`: frame k is the first post-step state at
/// or after time k / fps (frame 0 is the initial state).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Frames {
    pub nq: usize,
    /// Simulation time of each frame (s).
    pub times: Vec<f64>,
    /// `nq` values per frame, frame-major.
    pub qpos: Vec<f64>,
    /// Whether the push acted on the step that led to each frame.
    pub pushing: Vec<bool>,
}

impl Frames {
    pub fn len(&self) -> usize {
        self.times.len()
    }

    pub fn is_empty(&self) -> bool {
        self.times.is_empty()
    }

    /// qpos of frame `k`.
    pub fn qpos(&self, k: usize) -> &[f64] {
        &self.qpos[k * self.nq..(k + 1) * self.nq]
    }
}

/// Frames in a second beyond which a recording is refused (a frame per
/// step of MuJoCo's smallest sensible timestep).
const MAX_FPS: f64 = 1.0e4;

/// The number of frames over `seconds` at `fps`: t = 0, 1/fps, ... up to
/// `seconds` (never past the end of the simulation).
pub fn frame_count(seconds: f64, fps: f64) -> Result<usize> {
    if !(fps.is_finite() && fps > 0.0 && fps <= MAX_FPS) {
        return Err(Error::Config(format!(
            "frame rate {fps} is not in (0, {MAX_FPS}]: give fps a positive number such as 25"
        )));
    }
    Ok((seconds * fps + 1e-9).floor() as usize + 1)
}

/// Collects one cell's frames as its simulation advances.
#[derive(Debug, Clone)]
pub struct FrameRecorder {
    fps: f64,
    count: usize,
    frames: Frames,
}

impl FrameRecorder {
    /// Starts with frame 0, the initial state.
    pub fn new(fps: f64, count: usize, initial_qpos: &[f64]) -> FrameRecorder {
        let nq = initial_qpos.len();
        let mut frames = Frames {
            nq,
            times: Vec::with_capacity(count),
            qpos: Vec::with_capacity(count * nq),
            pushing: Vec::with_capacity(count),
        };
        frames.times.push(0.0);
        frames.qpos.extend_from_slice(initial_qpos);
        frames.pushing.push(false);
        FrameRecorder { fps, count, frames }
    }

    /// The state after a step that ended at time `t`.
    pub fn offer(&mut self, t: f64, qpos: &[f64], pushing: bool) {
        // the tolerance absorbs the rounding of the accumulated clock
        while self.frames.len() < self.count && t >= self.frames.len() as f64 / self.fps - 1e-9 {
            self.frames.times.push(t);
            self.frames.qpos.extend_from_slice(qpos);
            self.frames.pushing.push(pushing);
        }
    }

    /// All frames; a cell that stopped early (it diverged) holds its last
    /// good state to the end, at the frame times it would have had.
    pub fn finish(mut self) -> Frames {
        let nq = self.frames.nq;
        while self.frames.len() < self.count {
            let k = self.frames.len();
            let last = self.frames.qpos[(k - 1) * nq..k * nq].to_vec();
            self.frames.times.push(k as f64 / self.fps);
            self.frames.qpos.extend_from_slice(&last);
            self.frames.pushing.push(false);
        }
        self.frames
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_include_both_ends() {
        assert_eq!(frame_count(1.0, 20.0).unwrap(), 21);
        assert_eq!(frame_count(0.2, 10.0).unwrap(), 3);
        assert_eq!(frame_count(1.5, 15.0).unwrap(), 23); // 22.5 frame periods: the last at 1.4667 s
        assert!(frame_count(1.0, 0.0).is_err());
        assert!(frame_count(1.0, f64::NAN).is_err());
    }

    #[test]
    fn frames_are_the_first_states_at_or_after_each_frame_time() {
        // dt 0.03 s against frames every 0.1 s: states at 0.03, 0.06, ...
        let mut r = FrameRecorder::new(10.0, 4, &[0.0]);
        let mut t = 0.0;
        for k in 1..=12 {
            t += 0.03;
            r.offer(t, &[k as f64], k == 4);
        }
        let f = r.finish();
        assert_eq!(f.len(), 4);
        // 0.12 >= 0.1, 0.21 >= 0.2, 0.30 >= 0.3 (within the tolerance)
        assert_eq!(f.qpos, vec![0.0, 4.0, 7.0, 10.0]);
        assert_eq!(f.pushing, vec![false, true, false, false]);
        assert!((f.times[1] - 0.12).abs() < 1e-12);
    }

    #[test]
    fn a_cell_that_stops_holds_its_last_state() {
        let mut r = FrameRecorder::new(10.0, 4, &[1.0, 2.0]);
        r.offer(0.1, &[3.0, 4.0], false);
        let f = r.finish();
        assert_eq!(f.len(), 4);
        assert_eq!(f.qpos(3), &[3.0, 4.0]);
        assert_eq!(f.times[3], 0.3);
    }

    #[test]
    fn fast_frames_repeat_a_state() {
        // two frames fall inside one step
        let mut r = FrameRecorder::new(100.0, 3, &[0.0]);
        r.offer(0.02, &[1.0], false);
        assert_eq!(r.finish().qpos, vec![0.0, 1.0, 1.0]);
    }
}

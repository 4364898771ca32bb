//! Shards: a deterministic part of a grid's cells, so one sweep can run as
//! N independent jobs (a Slurm job array, several machines) and be merged
//! back (`pupper merge`). Shard I of N (1-based) holds the cells whose grid
//! index is I-1 modulo N: interleaved, so the costly and the cheap corners
//! of a grid spread evenly over the shards.

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Shard {
    /// 1-based.
    pub index: u32,
    pub count: u32,
}

impl Shard {
    /// `I/N` with 1 <= I <= N.
    pub fn parse(text: &str) -> Result<Shard> {
        let bad = |why: &str| {
            Error::Config(format!(
                "--shard '{text}' {why}: give I/N with 1 <= I <= N, e.g. --shard 2/8 (in a Slurm array: --shard $SLURM_ARRAY_TASK_ID/N with --array=1-N)"
            ))
        };
        let (i, n) = text
            .trim()
            .split_once('/')
            .ok_or_else(|| bad("is not I/N"))?;
        let (i, n) = match (i.trim().parse::<u32>(), n.trim().parse::<u32>()) {
            (Ok(i), Ok(n)) => (i, n),
            _ => return Err(bad("is not two whole numbers")),
        };
        if n == 0 || i == 0 || i > n {
            return Err(bad("is out of range"));
        }
        Ok(Shard { index: i, count: n })
    }

    /// True when grid cell `index` is this shard's.
    pub fn holds(&self, index: usize) -> bool {
        index % self.count as usize == (self.index - 1) as usize
    }

    /// How many of a grid's `cells` this shard holds.
    pub fn cells_of(&self, cells: usize) -> usize {
        (0..cells).filter(|&i| self.holds(i)).count()
    }
}

impl std::fmt::Display for Shard {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_and_refuses() {
        assert_eq!(Shard::parse("2/3").unwrap(), Shard { index: 2, count: 3 });
        assert_eq!(Shard::parse(" 1 / 1 ").unwrap().to_string(), "1/1");
        for bad in ["0/3", "4/3", "1/0", "3", "a/b", "-1/3", "1/3/4", ""] {
            let e = Shard::parse(bad).unwrap_err().to_string();
            assert!(e.contains("I/N"), "{bad}: {e}");
        }
    }

    #[test]
    fn shards_cover_every_cell_once_interleaved() {
        for n in 1..7u32 {
            for cells in [0usize, 1, 5, 16, 17] {
                let mut seen = vec![0; cells];
                for i in 1..=n {
                    let s = Shard { index: i, count: n };
                    let mine: Vec<usize> = (0..cells).filter(|&c| s.holds(c)).collect();
                    assert_eq!(mine.len(), s.cells_of(cells));
                    for c in mine {
                        seen[c] += 1;
                    }
                }
                assert!(seen.iter().all(|&k| k == 1), "{n} {cells}");
            }
        }
        // interleaved: shard 2 of 3 holds cells 1, 4, 7, ...
        let s = Shard { index: 2, count: 3 };
        assert_eq!(
            (0..9).filter(|&c| s.holds(c)).collect::<Vec<_>>(),
            [1, 4, 7]
        );
    }
}

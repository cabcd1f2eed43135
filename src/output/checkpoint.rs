//! Checkpoints of a run folder: what a killed run had finished, so that `--resume` carries on.
//!
//! A run keeps, in the hidden folder `.penumbra-resume/` of its output folder, a journal of the
//! parts it has finished (a stage, a block of map rows, a rendered frame): each part's output
//! files with their sha256 and, where the part's result is needed again later (the map's per-pixel
//! sums), a binary blob. Every journal update and every blob is written atomically (temp file +
//! rename), so a kill at any moment leaves a journal that describes finished work only.
//!
//! The journal carries a fingerprint of everything that decides the outputs (penumbra's version,
//! the scenario as parsed, the kernels' and DEMs' sha256): `--resume` refuses a folder whose run
//! had another fingerprint, and skips a part only when its files are still there with the recorded
//! hashes. A run that completes removes the folder after writing its manifest (`run.json`).
//!
//! Test hook: with `PENUMBRA_TEST_EXIT_AFTER_CHECKPOINTS=N` the process exits (code 137, no
//! clean-up, as a kill would leave it) right after its N-th checkpoint.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// The hidden folder of a run folder that holds its checkpoints.
pub const CHECKPOINT_DIR: &str = ".penumbra-resume";

const JOURNAL: &str = "journal.json";
const JOURNAL_FORMAT: u32 = 1;

/// Checkpoints taken by this process (for the test hook).
static TAKEN: AtomicU64 = AtomicU64::new(0);

#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
struct DoneFile {
    /// Path relative to the run folder.
    path: String,
    sha256: String,
}

#[derive(Debug, Clone, Default, serde::Serialize, serde::Deserialize)]
struct Part {
    /// The files the part wrote.
    files: Vec<DoneFile>,
    /// What the part needs to tell a resumed run (e.g. the backend that ran it).
    note: String,
}

#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
struct Journal {
    format: u32,
    /// sha256 of the run's decisive inputs and parameters.
    fingerprint: String,
    /// Finished parts by key.
    done: BTreeMap<String, Part>,
}

/// The checkpoints of one run folder (see the module documentation).
#[derive(Debug)]
pub struct Checkpoint {
    out_dir: PathBuf,
    dir: PathBuf,
    journal: Journal,
    /// Parts found finished when the run started (for the summary line).
    resumed_parts: usize,
}

impl Checkpoint {
    /// Opens the checkpoints of `out_dir` for a run with `fingerprint`. With `resume`, an
    /// unfinished run's journal is taken over (an error if it had another fingerprint); without,
    /// any old checkpoints are discarded. Returns the checkpoint and a line for the user, if any.
    pub fn open(
        out_dir: &Path,
        fingerprint: &str,
        resume: bool,
    ) -> Result<(Self, Option<String>), String> {
        let dir = out_dir.join(CHECKPOINT_DIR);
        let fresh = Journal {
            format: JOURNAL_FORMAT,
            fingerprint: fingerprint.to_string(),
            done: BTreeMap::new(),
        };
        let old = read_journal(&dir);
        let (journal, note) = match (resume, old) {
            (true, Ok(Some(j))) => {
                if j.format != JOURNAL_FORMAT || j.fingerprint != fingerprint {
                    return Err(format!(
                        "cannot resume {}: its unfinished run had other inputs or parameters \
                         (scenario, kernels, DEMs or penumbra version); run without --resume to \
                         start over",
                        out_dir.display()
                    ));
                }
                let n = j.done.len();
                (
                    j,
                    Some(format!(
                        "penumbra: resuming the unfinished run in {} ({n} finished part(s) kept)",
                        out_dir.display()
                    )),
                )
            }
            (true, Ok(None)) => (
                fresh,
                Some(format!(
                    "penumbra: nothing to resume in {}; starting the run",
                    out_dir.display()
                )),
            ),
            (true, Err(e)) => {
                return Err(format!(
                    "cannot resume {}: its checkpoint journal is unreadable ({e}); run without \
                     --resume to start over",
                    out_dir.display()
                ));
            }
            (false, old) => {
                let note = dir.exists().then(|| {
                    format!(
                        "penumbra: discarding the checkpoints of an unfinished run in {} (give \
                         --resume to continue it instead)",
                        out_dir.display()
                    )
                });
                if !matches!(old, Ok(None)) || dir.exists() {
                    std::fs::remove_dir_all(&dir)
                        .map_err(|e| format!("removing {}: {e}", dir.display()))?;
                }
                (fresh, note)
            }
        };
        std::fs::create_dir_all(&dir).map_err(|e| format!("creating {}: {e}", dir.display()))?;
        let resumed_parts = journal.done.len();
        let cp = Checkpoint {
            out_dir: out_dir.to_path_buf(),
            dir,
            journal,
            resumed_parts,
        };
        cp.write_journal()?;
        Ok((cp, note))
    }

    /// Parts that were already finished when this run started.
    pub fn resumed_parts(&self) -> usize {
        self.resumed_parts
    }

    /// Whether part `key` is finished: recorded, and every file it wrote still there with the
    /// recorded contents.
    pub fn is_done(&self, key: &str) -> bool {
        let Some(part) = self.journal.done.get(key) else {
            return false;
        };
        part.files
            .iter()
            .all(|f| super::sha256_file(&self.out_dir.join(&f.path)).is_ok_and(|h| h == f.sha256))
    }

    /// The files part `key` wrote (relative to the run folder) and its note, if it is recorded.
    pub fn part(&self, key: &str) -> Option<(Vec<String>, &str)> {
        self.journal.done.get(key).map(|p| {
            (
                p.files.iter().map(|f| f.path.clone()).collect(),
                p.note.as_str(),
            )
        })
    }

    /// Records part `key` as finished with the files it wrote (relative to the run folder) and
    /// a note for a resumed run.
    pub fn mark_done(&mut self, key: &str, files: &[String], note: &str) -> Result<(), String> {
        let done = files
            .iter()
            .map(|f| {
                super::sha256_file(&self.out_dir.join(f))
                    .map(|sha256| DoneFile {
                        path: f.clone(),
                        sha256,
                    })
                    .map_err(|e| format!("hashing {f} for the checkpoint: {e}"))
            })
            .collect::<Result<Vec<_>, _>>()?;
        self.journal.done.insert(
            key.to_string(),
            Part {
                files: done,
                note: note.to_string(),
            },
        );
        self.write_journal()?;
        taken();
        Ok(())
    }

    /// The blob of part `key`, if the part is finished and its blob is there.
    pub fn load_blob(&self, key: &str) -> Option<Vec<u8>> {
        if !self.journal.done.contains_key(key) {
            return None;
        }
        std::fs::read(self.blob_path(key)).ok()
    }

    /// Stores `bytes` as part `key`'s blob and records the part as finished (no output files).
    pub fn store_blob(&mut self, key: &str, bytes: &[u8]) -> Result<(), String> {
        let path = self.blob_path(key);
        write_file(&path, bytes)?;
        self.mark_done(key, &[], "")
    }

    /// The run is complete: removes the checkpoints.
    pub fn finish(self) {
        let _ = std::fs::remove_dir_all(&self.dir);
    }

    fn blob_path(&self, key: &str) -> PathBuf {
        let safe: String = key
            .chars()
            .map(|c| if c.is_ascii_alphanumeric() { c } else { '_' })
            .collect();
        self.dir.join(format!("{safe}.bin"))
    }

    fn write_journal(&self) -> Result<(), String> {
        let path = self.dir.join(JOURNAL);
        let text = serde_json::to_string_pretty(&self.journal).map_err(|e| e.to_string())?;
        write_file(&path, text.as_bytes())
    }
}

impl Drop for Checkpoint {
    /// A run that fails before finishing any part leaves no checkpoint folder (nothing to resume,
    /// and a bad input leaves no file); one with finished parts keeps them for `--resume`.
    fn drop(&mut self) {
        if self.journal.done.is_empty() {
            let _ = std::fs::remove_dir_all(&self.dir);
        }
    }
}

/// Writes `bytes` to `path` atomically.
fn write_file(path: &Path, bytes: &[u8]) -> Result<(), String> {
    super::write_atomic(path, |w| {
        w.write_all(bytes).map_err(|source| super::OutputError::Io {
            path: path.display().to_string(),
            source,
        })
    })
    .map_err(|e| e.to_string())
}

fn read_journal(dir: &Path) -> Result<Option<Journal>, String> {
    let path = dir.join(JOURNAL);
    if !path.exists() {
        return Ok(None);
    }
    let text = super::guard::read_small_text(&path, 64 << 20).map_err(|e| e.to_string())?;
    serde_json::from_str(&text)
        .map(Some)
        .map_err(|e| e.to_string())
}

/// Counts a checkpoint; exits as a kill would when the test hook asks for it.
fn taken() {
    let n = TAKEN.fetch_add(1, Ordering::SeqCst) + 1;
    if let Some(limit) = std::env::var("PENUMBRA_TEST_EXIT_AFTER_CHECKPOINTS")
        .ok()
        .and_then(|v| v.parse::<u64>().ok())
        && n >= limit
    {
        eprintln!("penumbra: test hook: exiting after checkpoint {n}");
        std::process::exit(137);
    }
}

/// A large input's size and modification time, for a fingerprint (hashing it could take minutes).
pub fn file_stamp(path: &Path) -> std::io::Result<String> {
    let meta = std::fs::metadata(path)?;
    Ok(format!(
        "{} bytes, modified {:?}",
        meta.len(),
        meta.modified().ok()
    ))
}

/// sha256 (hex) of `parts`, each length-prefixed: a fingerprint of a run's decisive inputs.
pub fn fingerprint(parts: &[&[u8]]) -> String {
    use sha2::Digest as _;
    let mut h = sha2::Sha256::new();
    for p in parts {
        h.update((p.len() as u64).to_le_bytes());
        h.update(p);
    }
    format!("{:x}", h.finalize())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finished_parts_survive_and_other_fingerprints_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path();
        let (mut cp, note) = Checkpoint::open(out, "abc", false).unwrap();
        assert!(note.is_none());
        std::fs::write(out.join("a.csv"), "1,2\n").unwrap();
        cp.mark_done("series", &["a.csv".into()], "cpu").unwrap();
        cp.store_blob("map rows 0-4", &[1, 2, 3]).unwrap();
        drop(cp);
        let (cp, note) = Checkpoint::open(out, "abc", true).unwrap();
        assert!(note.unwrap().contains("2 finished part(s)"));
        assert!(cp.is_done("series"));
        assert_eq!(
            cp.part("series").unwrap(),
            (vec!["a.csv".to_string()], "cpu")
        );
        assert_eq!(cp.load_blob("map rows 0-4").unwrap(), vec![1, 2, 3]);
        assert!(cp.load_blob("map rows 4-8").is_none());
        // A changed output file un-finishes its part.
        std::fs::write(out.join("a.csv"), "1,3\n").unwrap();
        assert!(!cp.is_done("series"));
        drop(cp);
        let err = Checkpoint::open(out, "other", true).unwrap_err();
        assert!(err.contains("other inputs or parameters"), "{err}");
        // Without --resume the old checkpoints go.
        let (cp, note) = Checkpoint::open(out, "other", false).unwrap();
        assert!(note.unwrap().contains("discarding"));
        assert!(!cp.is_done("series"));
        cp.finish();
        assert!(!out.join(CHECKPOINT_DIR).exists());
    }
}

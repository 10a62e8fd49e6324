//! The run's temporary directory and the slab files in it.
//!
//! Everything the out-of-core path writes goes into one directory it creates for itself under
//! the directory the user chose (or the system's); [`Scratch`] owns it and removes it with
//! everything in it when dropped, so it is gone after a success, an error, a cancel or a panic
//! that unwinds.
//!
//! A slab's points are kept as fixed records in input order: the position in `f64` (the
//! file's `double`, or its `float` widened exactly), the normal as read and the confidence
//! (1 when the input has none), 40 bytes a point, little-endian.

use super::OutOfCoreError;
use std::fs::{self, File};
use std::io::{self, BufReader, BufWriter, Read, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// The temporary directory of one run, removed with its contents when dropped by the member of
/// the team that made it (the others [`Scratch::join`] it).
#[derive(Debug)]
pub(crate) struct Scratch {
    dir: PathBuf,
    made_here: bool,
}

impl Scratch {
    /// Creates a new, empty directory `psr-out-of-core-<pid>-<n>` under `parent` (the
    /// system's temporary directory when `None`); a name already taken is skipped.
    pub(crate) fn create(parent: Option<&Path>) -> Result<Scratch, OutOfCoreError> {
        static RUNS: AtomicU64 = AtomicU64::new(0);
        let parent = parent.map_or_else(std::env::temp_dir, Path::to_path_buf);
        loop {
            let n = RUNS.fetch_add(1, Ordering::Relaxed);
            let dir = parent.join(format!("psr-out-of-core-{}-{n}", std::process::id()));
            match fs::create_dir(&dir) {
                Ok(()) => {
                    return Ok(Scratch {
                        dir,
                        made_here: true,
                    })
                }
                Err(e) if e.kind() == io::ErrorKind::AlreadyExists => continue,
                Err(source) => {
                    return Err(OutOfCoreError::Scratch {
                        action: "create the temporary directory",
                        path: dir,
                        source,
                    })
                }
            }
        }
    }

    /// The directory `dir` another member of the team made (and removes); see
    /// [`Scratch::find_token`] for the check that this member sees the same directory.
    pub(crate) fn join(dir: PathBuf) -> Scratch {
        Scratch {
            dir,
            made_here: false,
        }
    }

    /// Leaves `token` in the directory, for the other members of a team to find
    /// ([`Scratch::find_token`]).
    pub(crate) fn leave_token(&self, token: u64) -> Result<(), OutOfCoreError> {
        let path = self.file(TOKEN_FILE);
        fs::write(&path, token.to_le_bytes())
            .map_err(scratch_error("write the team's token", &path))
    }

    /// Whether this member sees the directory the member that made it sees: it must hold the
    /// `token` that member left. Members on different machines each have their own system
    /// temporary directory, so a run across machines needs a directory on a file system they
    /// share; without this check the first slab file written or read would fail with a bare
    /// "No such file or directory" (or, were a stale directory of the same name there, mix
    /// another run's files into this one).
    pub(crate) fn find_token(&self, token: u64) -> Result<(), OutOfCoreError> {
        let path = self.file(TOKEN_FILE);
        let not_shared = |source| OutOfCoreError::Scratch {
            action: "find the temporary directory the team's first member made (every member \
                     must see the same directory: with members on several machines, one on a \
                     file system they share)",
            path: path.clone(),
            source,
        };
        match fs::read(&path) {
            Ok(bytes) if bytes == token.to_le_bytes() => Ok(()),
            Ok(_) => Err(not_shared(io::Error::other(
                "it holds another run's token: a directory of the same name, not the one made \
                 for this run",
            ))),
            Err(source) => Err(not_shared(source)),
        }
    }

    pub(crate) fn path(&self) -> &Path {
        &self.dir
    }

    /// The path of the file named `name` in the directory.
    pub(crate) fn file(&self, name: &str) -> PathBuf {
        self.dir.join(name)
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        // Nothing to report to: a directory that cannot be removed is left to the system's
        // cleaning of its temporary directory.
        if self.made_here {
            let _ = fs::remove_dir_all(&self.dir);
        }
    }
}

/// The file in which the member that made the directory leaves a token for the others.
const TOKEN_FILE: &str = "team-token";

/// A number no other run is likely to pick: the team's token for its directory and output.
pub(crate) fn fresh_token() -> u64 {
    use std::hash::BuildHasher;
    let now = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |t| t.as_nanos());
    // Each `RandomState` is seeded from the system's randomness.
    std::collections::hash_map::RandomState::new().hash_one((std::process::id(), now))
}

/// One point as a slab file keeps it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct PointRecord {
    pub(crate) position: [f64; 3],
    pub(crate) normal: [f32; 3],
    pub(crate) confidence: f32,
}

const RECORD_BYTES: usize = 40;

impl PointRecord {
    fn to_bytes(self) -> [u8; RECORD_BYTES] {
        let mut out = [0u8; RECORD_BYTES];
        for (a, v) in self.position.iter().enumerate() {
            out[8 * a..8 * a + 8].copy_from_slice(&v.to_le_bytes());
        }
        for (a, v) in self.normal.iter().enumerate() {
            out[24 + 4 * a..28 + 4 * a].copy_from_slice(&v.to_le_bytes());
        }
        out[36..40].copy_from_slice(&self.confidence.to_le_bytes());
        out
    }

    fn from_bytes(bytes: &[u8; RECORD_BYTES]) -> Self {
        let f64_at = |i: usize| f64::from_le_bytes(bytes[i..i + 8].try_into().expect("8 bytes"));
        let f32_at = |i: usize| f32::from_le_bytes(bytes[i..i + 4].try_into().expect("4 bytes"));
        PointRecord {
            position: [f64_at(0), f64_at(8), f64_at(16)],
            normal: [f32_at(24), f32_at(28), f32_at(32)],
            confidence: f32_at(36),
        }
    }
}

/// Appends records to one slab's file.
pub(crate) struct SlabWriter {
    path: PathBuf,
    out: BufWriter<File>,
    pub(crate) records: u64,
}

/// The error of `action` on `path` in the temporary directory, for `map_err`. The path is
/// copied only when there is an error: the slab files are read and written a record at a time,
/// each through `map_err`, and copying the path for every record (and, before the lists went
/// by chunks, every word) cost an out-of-core run up to 30 % of its time in `malloc`, `free`
/// and `Path::to_path_buf` (Buddha at depth 10 in 8 slabs: 38-40 s, now 27-28 s).
pub(crate) fn scratch_error<'a>(
    action: &'static str,
    path: &'a Path,
) -> impl FnOnce(io::Error) -> OutOfCoreError + 'a {
    move |source| OutOfCoreError::Scratch {
        action,
        path: path.to_path_buf(),
        source,
    }
}

impl SlabWriter {
    /// A new, empty file at `path`, written through a buffer of `buffer` bytes.
    pub(crate) fn create(path: PathBuf, buffer: usize) -> Result<SlabWriter, OutOfCoreError> {
        let file = File::create(&path).map_err(scratch_error("create a slab file", &path))?;
        Ok(SlabWriter {
            out: BufWriter::with_capacity(buffer, file),
            path,
            records: 0,
        })
    }

    pub(crate) fn push(&mut self, record: PointRecord) -> Result<(), OutOfCoreError> {
        self.records += 1;
        self.out
            .write_all(&record.to_bytes())
            .map_err(scratch_error("write a slab file", &self.path))
    }

    /// Flushes the file and gives its path.
    pub(crate) fn finish(mut self) -> Result<PathBuf, OutOfCoreError> {
        self.out
            .flush()
            .map_err(scratch_error("write a slab file", &self.path))?;
        Ok(self.path)
    }
}

/// Every record of the slab files at `paths`, one file after the other, each in the order
/// written.
pub(crate) fn read_slab(paths: &[PathBuf]) -> Result<Vec<PointRecord>, OutOfCoreError> {
    let mut records = Vec::new();
    for path in paths {
        read_slab_into(path, &mut records)?;
    }
    Ok(records)
}

fn read_slab_into(path: &Path, records: &mut Vec<PointRecord>) -> Result<(), OutOfCoreError> {
    let file = File::open(path).map_err(scratch_error("open a slab file", path))?;
    let len = file
        .metadata()
        .map_err(scratch_error("read a slab file", path))?
        .len();
    let count = (len / RECORD_BYTES as u64) as usize;
    records.reserve(count);
    let mut input = BufReader::with_capacity(1 << 20, file);
    let mut bytes = [0u8; RECORD_BYTES];
    for _ in 0..count {
        input
            .read_exact(&mut bytes)
            .map_err(scratch_error("read a slab file", path))?;
        records.push(PointRecord::from_bytes(&bytes));
    }
    Ok(())
}

/// Writes lists of 8-byte values (packed keys or coefficients), each with its length, to
/// `path`: a slab's solution between the passes that make and read it.
pub(crate) fn write_lists<T: Copy + Into<Word>>(
    path: &Path,
    lists: &[Vec<T>],
) -> Result<(), OutOfCoreError> {
    let error = || scratch_error("write a slab's solution", path);
    let file = File::create(path).map_err(error())?;
    let mut out = BufWriter::with_capacity(1 << 20, file);
    out.write_all(&(lists.len() as u64).to_le_bytes())
        .map_err(error())?;
    let mut bytes = Vec::with_capacity(LIST_CHUNK * 8);
    for list in lists {
        out.write_all(&(list.len() as u64).to_le_bytes())
            .map_err(error())?;
        for chunk in list.chunks(LIST_CHUNK) {
            bytes.clear();
            bytes.extend(chunk.iter().flat_map(|&v| v.into().0.to_le_bytes()));
            out.write_all(&bytes).map_err(error())?;
        }
    }
    out.flush().map_err(error())
}

/// Values of a list read or written at a time by [`read_lists`] and [`write_lists`].
const LIST_CHUNK: usize = 8192;

/// Reads what [`write_lists`] wrote.
pub(crate) fn read_lists<T: From<Word>>(path: &Path) -> Result<Vec<Vec<T>>, OutOfCoreError> {
    let error = || scratch_error("read a slab's solution", path);
    let file = File::open(path).map_err(error())?;
    let mut input = BufReader::with_capacity(1 << 20, file);
    let mut bytes = vec![0u8; LIST_CHUNK * 8];
    let next = |input: &mut BufReader<File>| -> Result<u64, OutOfCoreError> {
        let mut word = [0u8; 8];
        input.read_exact(&mut word).map_err(error())?;
        Ok(u64::from_le_bytes(word))
    };
    let lists = next(&mut input)?;
    let mut out = Vec::with_capacity(lists as usize);
    for _ in 0..lists {
        let len = next(&mut input)? as usize;
        let mut list = Vec::with_capacity(len);
        while list.len() < len {
            let chunk = &mut bytes[..(len - list.len()).min(LIST_CHUNK) * 8];
            input.read_exact(chunk).map_err(error())?;
            list.extend(chunk.chunks_exact(8).map(|word| {
                T::from(Word(u64::from_le_bytes(
                    word.try_into().expect("chunks of eight bytes"),
                )))
            }));
        }
        out.push(list);
    }
    Ok(out)
}

/// Eight bytes as they are stored: a `u64` as it is, an `f64` by its bits.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Word(u64);

impl From<u64> for Word {
    fn from(v: u64) -> Self {
        Word(v)
    }
}

impl From<f64> for Word {
    fn from(v: f64) -> Self {
        Word(v.to_bits())
    }
}

impl From<Word> for u64 {
    fn from(w: Word) -> Self {
        w.0
    }
}

impl From<Word> for f64 {
    fn from(w: Word) -> Self {
        f64::from_bits(w.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Proves the records come back as written, the parts of a slab in their order, and the
    /// directory is gone after the guard is dropped, whatever it holds.
    #[test]
    fn slab_files_round_trip_and_the_directory_goes_with_its_guard() {
        let scratch = Scratch::create(None).expect("a temporary directory");
        let dir = scratch.path().to_path_buf();
        assert!(dir.is_dir());
        let records: Vec<PointRecord> = (0..1000)
            .map(|i| PointRecord {
                position: [i as f64 * 0.1, -1e6 + i as f64, 1.0 / (i + 1) as f64],
                normal: [0.0, (i as f32).sin(), 1.0],
                confidence: i as f32 * 0.5,
            })
            .collect();
        // Written as three parts (one of them empty), read back one after the other.
        let mut paths = Vec::new();
        for (part, range) in [0..600, 600..600, 600..1000].into_iter().enumerate() {
            let file = scratch.file(&format!("slab-0-from-{part}.points"));
            let mut writer = SlabWriter::create(file, 4096).expect("writable");
            for &r in &records[range.clone()] {
                writer.push(r).expect("written");
            }
            assert_eq!(writer.records, range.len() as u64);
            paths.push(writer.finish().expect("flushed"));
        }
        assert_eq!(read_slab(&paths).expect("readable"), records);
        let lists = vec![vec![1.5f64, -0.0, f64::MIN_POSITIVE], vec![], vec![7.0]];
        write_lists(&scratch.file("lists"), &lists).expect("written");
        let back: Vec<Vec<f64>> = read_lists(&scratch.file("lists")).expect("read");
        assert_eq!(
            back.iter()
                .flatten()
                .map(|v| v.to_bits())
                .collect::<Vec<_>>(),
            lists
                .iter()
                .flatten()
                .map(|v| v.to_bits())
                .collect::<Vec<_>>()
        );
        assert_eq!(back.iter().map(Vec::len).collect::<Vec<_>>(), vec![3, 0, 1]);
        fs::create_dir(scratch.file("nested")).expect("a subdirectory");
        drop(scratch);
        assert!(!dir.exists(), "{} left behind", dir.display());
    }

    /// Proves a member finds the directory's token only where the member that made it left
    /// that token: a directory it cannot see, or one holding another token, is refused with a
    /// message that says the directory must be shared.
    #[test]
    fn a_member_joins_only_the_directory_holding_its_teams_token() {
        let made = Scratch::create(None).expect("a temporary directory");
        let token = fresh_token();
        made.leave_token(token).expect("written");
        let joined = Scratch::join(made.path().to_path_buf());
        joined.find_token(token).expect("the same directory");
        for (dir, wrong) in [
            (made.path().to_path_buf(), token ^ 1),
            (made.path().join("elsewhere"), token),
        ] {
            let message = Scratch::join(dir)
                .find_token(wrong)
                .expect_err("not this team's directory")
                .to_string();
            assert!(message.contains("file system they share"), "{message}");
        }
        assert_ne!(fresh_token(), fresh_token(), "tokens differ");
        drop(joined);
        assert!(
            made.path().is_dir(),
            "only the member that made it removes it"
        );
    }

    /// Proves a parent that cannot hold the directory gives an error naming the path.
    #[test]
    fn a_missing_parent_is_a_clear_error() {
        let parent = std::env::temp_dir().join("psr-no-such-parent/deeper");
        let error = Scratch::create(Some(&parent)).expect_err("no parent");
        let message = error.to_string();
        assert!(message.contains("psr-no-such-parent"), "{message}");
    }
}

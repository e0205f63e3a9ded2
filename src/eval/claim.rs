//! Claim files: how concurrent shards of one evaluation (processes on one machine, or tasks
//! of a Slurm array or Kubernetes Job sharing a filesystem) compute each cache entry once.
//!
//! Before computing a missing entry, a process creates `<entry>.claim` with `O_EXCL`
//! (`create_new`), holding its host, process id and a random token. Another process that
//! needs the same entry finds the claim and waits for the entry to appear instead of
//! computing it too. The holder touches the claim while it works (at most every
//! [`HEARTBEAT`]) and removes it when the entry is written or the work fails.
//!
//! A claim is **stale**, and is taken over, when its holder is on this host and its process
//! no longer exists (a killed shard: its unit in flight is redone at once, and only that
//! unit, since finished entries are already written), or when it has not been touched for
//! [`STALE_CLAIM`] (a holder on another node that died). Taking over renames the stale file
//! away first and checks it renamed the one it judged, so two processes that find one stale
//! claim do not both take it. A lost race only costs duplicated work, never a wrong entry:
//! entries are written atomically and their bytes depend only on their key.

use std::fs;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant, SystemTime};

/// How often a holder refreshes its claim's modification time.
pub const HEARTBEAT: Duration = Duration::from_secs(30);

/// A claim untouched for this long is stale, whoever holds it.
pub const STALE_CLAIM: Duration = Duration::from_secs(15 * 60);

/// A claim file that exists but does not name a holder (empty or cut short: its holder was
/// killed between creating the file and writing its line) is stale once this old. A live
/// holder writes and syncs its line right after creating the file, so the grace only has to
/// cover that moment; without it such a file was waited on for ever (CI's kill once landed
/// there, and the rerun hung).
pub const UNREADABLE_CLAIM: Duration = Duration::from_secs(10);

/// This machine's name (`/proc/sys/kernel/hostname`; the claim's holder identity).
fn host() -> String {
    fs::read_to_string("/proc/sys/kernel/hostname")
        .or_else(|_| fs::read_to_string("/etc/hostname"))
        .map(|s| s.trim().to_owned())
        .unwrap_or_else(|_| "unknown-host".into())
}

/// A random token, unique to one claim.
fn token() -> u64 {
    use std::hash::{BuildHasher, Hasher};
    let mut h = std::collections::hash_map::RandomState::new().build_hasher();
    h.write_u128(SystemTime::now().duration_since(SystemTime::UNIX_EPOCH).unwrap_or_default().as_nanos());
    h.write_u32(std::process::id());
    h.finish()
}

/// Who holds a claim, as its file says.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Holder {
    /// Host name of the holder's machine (`?` when the claim file named no holder).
    pub host: String,
    /// The holder's process id on that host (0 when unknown).
    pub pid: u32,
    /// Random token unique to the claim: a takeover checks it renamed the claim it judged.
    pub token: u64,
}

impl Holder {
    fn parse(text: &str) -> Option<Self> {
        let mut it = text.split_whitespace();
        let host = it.next()?.to_owned();
        let pid = it.next()?.parse().ok()?;
        let token = u64::from_str_radix(it.next()?, 16).ok()?;
        Some(Self { host, pid, token })
    }

    fn text(&self) -> String {
        format!("{} {} {:016x}\n", self.host, self.pid, self.token)
    }

    /// Whether this holder is certainly gone: a process of this host that no longer exists.
    fn gone(&self) -> bool {
        self.host == host() && !Path::new(&format!("/proc/{}", self.pid)).exists()
    }
}

impl std::fmt::Display for Holder {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "process {} on {}", self.pid, self.host)
    }
}

/// A held claim; dropping it releases the claim.
#[derive(Debug)]
pub struct Claim {
    path: PathBuf,
    holder: Holder,
    touched: Instant,
}

/// What trying to claim an entry found.
#[derive(Debug)]
pub enum Attempt {
    /// The claim is ours: compute the entry.
    Acquired(Claim),
    /// Someone else is computing it.
    HeldBy(Holder),
}

/// The claim file of the entry at `entry`.
pub fn claim_path(entry: &Path) -> PathBuf {
    let mut name = entry.file_name().unwrap_or_default().to_os_string();
    name.push(".claim");
    entry.with_file_name(name)
}

/// Tries to claim the entry at `entry` (taking over a stale claim).
pub fn try_claim(entry: &Path) -> Result<Attempt, String> {
    let path = claim_path(entry);
    if let Some(dir) = path.parent() {
        fs::create_dir_all(dir).map_err(|e| format!("{}: cannot create folder: {e}", dir.display()))?;
    }
    let me = Holder { host: host(), pid: std::process::id(), token: token() };
    // Two rounds: the second follows the removal of a stale claim.
    for _ in 0..2 {
        match fs::OpenOptions::new().write(true).create_new(true).open(&path) {
            Ok(mut f) => {
                f.write_all(me.text().as_bytes())
                    .and_then(|_| f.sync_all())
                    .map_err(|e| format!("{}: cannot write claim: {e}", path.display()))?;
                return Ok(Attempt::Acquired(Claim { path, holder: me, touched: Instant::now() }));
            }
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {}
            Err(e) => return Err(format!("{}: cannot create claim: {e}", path.display())),
        }
        let holder = match read_claim_file(&path) {
            // Released between our attempt and this read: try again.
            ClaimFile::Missing => continue,
            // Being written, or left unwritten by a holder that died (see UNREADABLE_CLAIM).
            ClaimFile::Unreadable(age) if age <= UNREADABLE_CLAIM => continue,
            ClaimFile::Unreadable(_) => None,
            ClaimFile::Held(holder, age) if !(holder.gone() || age > STALE_CLAIM) => {
                return Ok(Attempt::HeldBy(holder));
            }
            ClaimFile::Held(holder, _) => Some(holder),
        };
        take_over(&path, holder.as_ref());
    }
    // Still contended after a takeover (someone else took it first), or a claim still being
    // written: wait for it.
    match read_claim_file(&path) {
        ClaimFile::Held(holder, _) => Ok(Attempt::HeldBy(holder)),
        _ => Ok(Attempt::HeldBy(Holder { host: "?".into(), pid: 0, token: 0 })),
    }
}

/// Removes the claim of a finished entry when its holder is gone or stale. A holder killed
/// after writing its entry but before removing its claim leaves such an orphan; the entry
/// is complete, so nobody will take the claim over, and without this it would outlive the run.
/// A live holder's claim is left to it (it removes it itself).
pub fn clear_orphan(entry: &Path) {
    let path = claim_path(entry);
    match read_claim_file(&path) {
        ClaimFile::Held(holder, age) if holder.gone() || age > STALE_CLAIM => take_over(&path, Some(&holder)),
        ClaimFile::Unreadable(age) if age > UNREADABLE_CLAIM => take_over(&path, None),
        _ => {}
    }
}

/// What a claim file holds.
enum ClaimFile {
    Missing,
    /// It exists but names no holder, and was last modified this long ago.
    Unreadable(Duration),
    /// Its holder, and how long ago it was last touched.
    Held(Holder, Duration),
}

fn read_claim_file(path: &Path) -> ClaimFile {
    let Ok(text) = fs::read_to_string(path) else { return ClaimFile::Missing };
    let Some(age) = fs::metadata(path).ok().and_then(|m| m.modified().ok()) else { return ClaimFile::Missing };
    let age = age.elapsed().unwrap_or_default();
    match Holder::parse(&text) {
        Some(holder) => ClaimFile::Held(holder, age),
        None => ClaimFile::Unreadable(age),
    }
}

/// Removes the stale claim of `judged` (`None`: an unreadable one) at `path`: renames it to
/// a name of ours, and puts it back if what we renamed is not the claim we judged (someone
/// took over first).
fn take_over(path: &Path, judged: Option<&Holder>) {
    let aside = path.with_extension(format!("claim.stale-{}-{:x}", std::process::id(), token()));
    if fs::rename(path, &aside).is_err() {
        return;
    }
    let renamed = fs::read_to_string(&aside).ok().and_then(|t| Holder::parse(&t));
    if renamed.as_ref() != judged {
        // A live claim: restore it unless a new one already exists (hard_link fails then).
        fs::hard_link(&aside, path).ok();
    }
    fs::remove_file(&aside).ok();
}

impl Claim {
    /// Refreshes the claim's modification time (at most every [`HEARTBEAT`]), so holders on
    /// other nodes can tell it is alive.
    pub fn heartbeat(&mut self) {
        if self.touched.elapsed() >= HEARTBEAT {
            self.touched = Instant::now();
            if let Ok(f) = fs::OpenOptions::new().write(true).open(&self.path) {
                f.set_modified(SystemTime::now()).ok();
            }
        }
    }

    /// The claim file (`<entry>.claim`).
    pub fn path(&self) -> &Path {
        &self.path
    }
}

impl Drop for Claim {
    fn drop(&mut self) {
        // Only our own claim: after a takeover of ours (we were judged stale), the file is
        // someone else's.
        if fs::read_to_string(&self.path).ok().and_then(|t| Holder::parse(&t)).as_ref() == Some(&self.holder) {
            fs::remove_file(&self.path).ok();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn temp_dir(tag: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("stereotrace-claim-{tag}-{}", std::process::id()));
        fs::remove_dir_all(&d).ok();
        fs::create_dir_all(&d).unwrap();
        d
    }

    #[test]
    fn one_claim_at_a_time_and_released_on_drop() {
        let dir = temp_dir("one");
        let entry = dir.join("a.bin");
        let Attempt::Acquired(claim) = try_claim(&entry).unwrap() else { panic!("first claim") };
        assert!(claim.path().is_file());
        match try_claim(&entry).unwrap() {
            Attempt::HeldBy(h) => assert_eq!(h.pid, std::process::id()),
            Attempt::Acquired(_) => panic!("claimed twice"),
        }
        drop(claim);
        assert!(!claim_path(&entry).exists());
        assert!(matches!(try_claim(&entry).unwrap(), Attempt::Acquired(_)));
        fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn a_dead_holders_claim_is_taken_over() {
        let dir = temp_dir("dead");
        let entry = dir.join("a.bin");
        // A process id of this host that no process has (above the kernel's pid_max).
        let dead = Holder { host: host(), pid: u32::MAX - 1, token: 7 };
        fs::write(claim_path(&entry), dead.text()).unwrap();
        let Attempt::Acquired(claim) = try_claim(&entry).unwrap() else { panic!("stale claim not taken over") };
        assert_eq!(claim.holder.pid, std::process::id());
        // A live holder on another host is waited for.
        drop(claim);
        let remote = Holder { host: "another-node".into(), pid: 1, token: 9 };
        fs::write(claim_path(&entry), remote.text()).unwrap();
        assert!(matches!(try_claim(&entry).unwrap(), Attempt::HeldBy(h) if h == remote));
        // Until it is stale by age.
        let f = fs::OpenOptions::new().write(true).open(claim_path(&entry)).unwrap();
        f.set_modified(SystemTime::now() - STALE_CLAIM - Duration::from_secs(1)).unwrap();
        assert!(matches!(try_claim(&entry).unwrap(), Attempt::Acquired(_)));
        fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn an_orphan_claim_of_a_finished_entry_is_cleared_and_a_live_one_kept() {
        let dir = temp_dir("orphan");
        let entry = dir.join("a.bin");
        fs::write(&entry, b"done").unwrap();
        let dead = Holder { host: host(), pid: u32::MAX - 1, token: 5 };
        fs::write(claim_path(&entry), dead.text()).unwrap();
        clear_orphan(&entry);
        assert!(!claim_path(&entry).exists(), "a dead holder's claim is removed");
        let live = Holder { host: host(), pid: std::process::id(), token: 6 };
        fs::write(claim_path(&entry), live.text()).unwrap();
        clear_orphan(&entry);
        assert_eq!(fs::read_to_string(claim_path(&entry)).unwrap(), live.text(), "a live claim is kept");
        clear_orphan(&dir.join("no-claim.bin"));
        fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn an_unwritten_claim_is_waited_for_briefly_then_taken_over() {
        // A holder killed between creating its claim and writing its line leaves an empty
        // file; a rerun once waited on one for ever.
        let dir = temp_dir("unwritten");
        let entry = dir.join("a.bin");
        fs::write(claim_path(&entry), b"").unwrap();
        assert!(
            matches!(try_claim(&entry).unwrap(), Attempt::HeldBy(h) if h.pid == 0),
            "a fresh one may be being written"
        );
        let age = |path: &Path, by: Duration| {
            let f = fs::OpenOptions::new().write(true).open(path).unwrap();
            f.set_modified(SystemTime::now() - by).unwrap();
        };
        age(&claim_path(&entry), UNREADABLE_CLAIM + Duration::from_secs(1));
        let Attempt::Acquired(claim) = try_claim(&entry).unwrap() else { panic!("unwritten claim not taken over") };
        assert_eq!(claim.holder.pid, std::process::id());
        drop(claim);
        // A half-written line is the same case; and an orphan of a finished entry is cleared.
        fs::write(&entry, b"done").unwrap();
        fs::write(claim_path(&entry), b"node-7 12").unwrap();
        clear_orphan(&entry);
        assert!(claim_path(&entry).exists(), "a fresh unreadable claim is left alone");
        age(&claim_path(&entry), UNREADABLE_CLAIM + Duration::from_secs(1));
        clear_orphan(&entry);
        assert!(!claim_path(&entry).exists(), "an old unreadable claim is removed");
        fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn a_claim_dropped_after_a_takeover_leaves_the_new_holders_file() {
        let dir = temp_dir("takeover");
        let entry = dir.join("a.bin");
        let Attempt::Acquired(mine) = try_claim(&entry).unwrap() else { panic!() };
        let other = Holder { host: host(), pid: 1, token: 3 };
        fs::write(claim_path(&entry), other.text()).unwrap();
        drop(mine);
        assert_eq!(fs::read_to_string(claim_path(&entry)).unwrap(), other.text());
        fs::remove_dir_all(&dir).ok();
    }
}

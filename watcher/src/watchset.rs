//! Which files the loop cares about and which folders it asks the OS to watch for them.
//!
//! Editors rarely modify a file in place: they write a temp file and rename it over, or delete
//! and recreate, and a watch on the file itself dies with the old inode. So the set watches the
//! *parent folder* of every watched file (non-recursively) and filters the folder's events down
//! to the watched names. A folder that does not exist (yet) is covered by watching its nearest
//! existing ancestor until it appears. Paths are compared in a resolved form (absolute, the
//! existing part canonicalized) because that is how the OS backends report them.

use notify::event::{AccessKind, AccessMode, ModifyKind};
use notify::{Event, EventKind, RecursiveMode};
use std::collections::{BTreeSet, HashMap};
use std::fs;
use std::path::{Path, PathBuf};

/// The watched files and the folder watches that serve them.
#[derive(Debug, Default)]
pub(crate) struct WatchSet {
    /// The paths as the job named them, duplicates removed, order kept.
    paths: Vec<PathBuf>,
    /// Resolved path (as events report it) -> indices into `paths`.
    keys: HashMap<PathBuf, Vec<usize>>,
    /// Folders currently registered with the backend.
    dirs: BTreeSet<PathBuf>,
}

/// What one backend event means for the loop.
#[derive(Debug, Default, PartialEq)]
pub(crate) struct Relevance {
    /// Watched paths (as the job named them) the event touched.
    pub changed: BTreeSet<PathBuf>,
    /// A folder on the way to a watched file appeared, vanished or moved: re-resolve and
    /// re-register the folder watches.
    pub resync: bool,
}

impl WatchSet {
    pub fn paths(&self) -> &[PathBuf] {
        &self.paths
    }

    /// Replaces the watched paths. Returns `(added, removed)` when the set differs.
    pub fn set_paths(&mut self, new: Vec<PathBuf>) -> Option<(Vec<PathBuf>, Vec<PathBuf>)> {
        let mut deduped = Vec::with_capacity(new.len());
        for path in new {
            if !deduped.contains(&path) {
                deduped.push(path);
            }
        }
        let added: Vec<PathBuf> = deduped
            .iter()
            .filter(|p| !self.paths.contains(p))
            .cloned()
            .collect();
        let removed: Vec<PathBuf> = self
            .paths
            .iter()
            .filter(|p| !deduped.contains(p))
            .cloned()
            .collect();
        self.paths = deduped;
        self.resolve_keys();
        if added.is_empty() && removed.is_empty() {
            None
        } else {
            Some((added, removed))
        }
    }

    fn resolve_keys(&mut self) {
        self.keys.clear();
        for (index, path) in self.paths.iter().enumerate() {
            for key in keys_for(path) {
                let indices = self.keys.entry(key).or_default();
                if !indices.contains(&index) {
                    indices.push(index);
                }
            }
        }
    }

    /// Registers the folders the current paths need and drops the ones they no longer need.
    /// Returns a warning for each folder that could not be watched.
    pub fn sync(&mut self, backend: &mut dyn notify::Watcher) -> Vec<String> {
        self.resolve_keys();
        let wanted: BTreeSet<PathBuf> = self
            .keys
            .keys()
            .filter_map(|key| key.parent().and_then(nearest_existing_dir))
            .collect();
        let mut warnings = Vec::new();
        for stale in self.dirs.difference(&wanted).cloned().collect::<Vec<_>>() {
            // The OS may already have dropped it (folder deleted); nothing to do then.
            let _ = backend.unwatch(&stale);
            self.dirs.remove(&stale);
        }
        for dir in wanted {
            if self.dirs.contains(&dir) {
                continue;
            }
            match backend.watch(&dir, RecursiveMode::NonRecursive) {
                Ok(()) => {
                    self.dirs.insert(dir);
                }
                Err(e) => warnings.push(format!(
                    "cannot watch folder {}: {e}; changes there are not seen",
                    dir.display()
                )),
            }
        }
        warnings
    }

    /// Forgets (and unregisters) the folder watches at or under `path`, so the next
    /// [`sync`](Self::sync) registers them afresh: a folder that was deleted and recreated has
    /// lost its OS watch even though the path is the same.
    pub fn forget_dirs_under(&mut self, path: &Path, backend: &mut dyn notify::Watcher) {
        let gone: Vec<PathBuf> = self
            .dirs
            .iter()
            .filter(|d| d.starts_with(path))
            .cloned()
            .collect();
        for dir in gone {
            let _ = backend.unwatch(&dir);
            self.dirs.remove(&dir);
        }
    }

    /// The folders currently registered (for tests and diagnostics).
    #[cfg(test)]
    pub fn dirs(&self) -> &BTreeSet<PathBuf> {
        &self.dirs
    }

    /// Which watched paths an event touches, and whether the folder watches need a resync.
    pub fn classify(&self, event: &Event) -> Relevance {
        let mut relevance = Relevance::default();
        if event.need_rescan() {
            // The backend lost events (queue overflow): assume everything changed.
            relevance.changed.extend(self.paths.iter().cloned());
            relevance.resync = true;
            return relevance;
        }
        if !kind_may_change_content(&event.kind) {
            return relevance;
        }
        let structural = matches!(
            event.kind,
            EventKind::Create(_)
                | EventKind::Remove(_)
                | EventKind::Modify(ModifyKind::Name(_))
                | EventKind::Modify(ModifyKind::Any)
                | EventKind::Any
                | EventKind::Other
        );
        for path in &event.paths {
            if let Some(indices) = self.keys.get(path) {
                relevance
                    .changed
                    .extend(indices.iter().map(|&i| self.paths[i].clone()));
            } else if structural {
                // A folder on the way to watched files (or a watched folder itself).
                let mut hit = false;
                for (key, indices) in &self.keys {
                    if key.starts_with(path) {
                        hit = true;
                        relevance
                            .changed
                            .extend(indices.iter().map(|&i| self.paths[i].clone()));
                    }
                }
                relevance.resync |= hit;
            }
        }
        relevance
    }
}

/// Reads (opening, closing after reading) never change a file; everything else may.
fn kind_may_change_content(kind: &EventKind) -> bool {
    match kind {
        EventKind::Access(AccessKind::Close(AccessMode::Write)) => true,
        EventKind::Access(_) => false,
        _ => true,
    }
}

/// The forms under which events may report `path`: the path in its resolved parent folder,
/// and, when it is a symlink, its target (whose folder is then watched too).
fn keys_for(path: &Path) -> Vec<PathBuf> {
    let absolute = std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf());
    let in_parent = match (absolute.parent(), absolute.file_name()) {
        (Some(parent), Some(name)) => resolve(parent).join(name),
        _ => resolve(&absolute),
    };
    let target = resolve(&absolute);
    if target == in_parent {
        vec![in_parent]
    } else {
        vec![in_parent, target]
    }
}

/// The absolute path with its longest existing prefix canonicalized (symlinks and `..`
/// resolved) and the missing rest appended as written.
fn resolve(path: &Path) -> PathBuf {
    let mut existing = path;
    let mut rest = Vec::new();
    loop {
        if let Ok(canonical) = fs::canonicalize(existing) {
            return rest
                .iter()
                .rev()
                .fold(canonical, |acc: PathBuf, name| acc.join(name));
        }
        match (existing.parent(), existing.file_name()) {
            (Some(parent), Some(name)) => {
                rest.push(name);
                existing = parent;
            }
            _ => return path.to_path_buf(),
        }
    }
}

/// `dir` if it is an existing folder, else its nearest existing ancestor folder.
fn nearest_existing_dir(dir: &Path) -> Option<PathBuf> {
    dir.ancestors().find(|d| d.is_dir()).map(Path::to_path_buf)
}

#[cfg(test)]
mod tests {
    use super::*;
    use notify::event::{CreateKind, DataChange, RemoveKind, RenameMode};

    /// A backend that records the calls instead of talking to the OS.
    #[derive(Default)]
    struct Recorder {
        watched: Vec<PathBuf>,
        unwatched: Vec<PathBuf>,
    }

    impl notify::Watcher for Recorder {
        fn new<F: notify::EventHandler>(_: F, _: notify::Config) -> notify::Result<Self> {
            Ok(Self::default())
        }
        fn watch(&mut self, path: &Path, mode: RecursiveMode) -> notify::Result<()> {
            assert_eq!(mode, RecursiveMode::NonRecursive);
            self.watched.push(path.to_path_buf());
            Ok(())
        }
        fn unwatch(&mut self, path: &Path) -> notify::Result<()> {
            self.unwatched.push(path.to_path_buf());
            Ok(())
        }
        fn kind() -> notify::WatcherKind {
            notify::WatcherKind::NullWatcher
        }
    }

    fn event(kind: EventKind, paths: &[&Path]) -> Event {
        paths
            .iter()
            .fold(Event::new(kind), |e, p| e.add_path(p.to_path_buf()))
    }

    #[test]
    fn watches_parent_folders_and_filters_to_watched_names() {
        let tmp = tempfile::tempdir().unwrap();
        let root = fs::canonicalize(tmp.path()).unwrap();
        fs::create_dir(root.join("src")).unwrap();
        let scene = root.join("scene.toml");
        let mesh = root.join("src").join("jelly.obj");
        let mut set = WatchSet::default();
        let mut backend = Recorder::default();
        assert_eq!(
            set.set_paths(vec![scene.clone(), mesh.clone(), scene.clone()]),
            Some((vec![scene.clone(), mesh.clone()], vec![]))
        );
        assert!(set.sync(&mut backend).is_empty());
        let mut watched = backend.watched.clone();
        watched.sort();
        assert_eq!(watched, vec![root.clone(), root.join("src")]);

        let write = event(
            EventKind::Modify(ModifyKind::Data(DataChange::Any)),
            &[&mesh],
        );
        assert_eq!(set.classify(&write).changed, BTreeSet::from([mesh.clone()]));
        // The output next to the scene, and reads of the watched file, do not count.
        let output = event(
            EventKind::Create(CreateKind::File),
            &[&root.join("out.glb")],
        );
        assert_eq!(set.classify(&output), Relevance::default());
        let read = event(
            EventKind::Access(AccessKind::Open(AccessMode::Any)),
            &[&mesh],
        );
        assert_eq!(set.classify(&read), Relevance::default());
        // A temp file renamed over the scene: the rename's target counts.
        let tmp_file = root.join(".scene.toml.swp");
        let rename = event(
            EventKind::Modify(ModifyKind::Name(RenameMode::Both)),
            &[&tmp_file, &scene],
        );
        assert_eq!(
            set.classify(&rename).changed,
            BTreeSet::from([scene.clone()])
        );
        // The source folder vanishing touches the file in it and asks for a resync.
        let gone = event(EventKind::Remove(RemoveKind::Folder), &[&root.join("src")]);
        let relevance = set.classify(&gone);
        assert!(relevance.resync);
        assert_eq!(relevance.changed, BTreeSet::from([mesh.clone()]));

        // Dropping a path drops its folder watch.
        assert_eq!(
            set.set_paths(vec![scene.clone()]),
            Some((vec![], vec![mesh.clone()]))
        );
        assert!(set.sync(&mut backend).is_empty());
        assert_eq!(backend.unwatched, vec![root.join("src")]);
        assert_eq!(set.dirs(), &BTreeSet::from([root.clone()]));
        assert_eq!(set.set_paths(vec![scene]), None);
    }

    #[test]
    fn a_missing_folder_is_covered_by_its_nearest_ancestor() {
        let tmp = tempfile::tempdir().unwrap();
        let root = fs::canonicalize(tmp.path()).unwrap();
        let mesh = root.join("later").join("deep").join("a.obj");
        let mut set = WatchSet::default();
        let mut backend = Recorder::default();
        set.set_paths(vec![mesh.clone()]);
        set.sync(&mut backend);
        assert_eq!(set.dirs(), &BTreeSet::from([root.clone()]));
        fs::create_dir_all(root.join("later").join("deep")).unwrap();
        let created = event(
            EventKind::Create(CreateKind::Folder),
            &[&root.join("later")],
        );
        let relevance = set.classify(&created);
        assert!(relevance.resync);
        assert_eq!(relevance.changed, BTreeSet::from([mesh.clone()]));
        set.sync(&mut backend);
        assert_eq!(
            set.dirs(),
            &BTreeSet::from([root.join("later").join("deep")])
        );
        assert_eq!(backend.unwatched, vec![root]);
    }

    #[test]
    fn relative_and_dotted_paths_match_the_reported_form() {
        let tmp = tempfile::tempdir().unwrap();
        let root = fs::canonicalize(tmp.path()).unwrap();
        fs::create_dir(root.join("a")).unwrap();
        let dotted = root.join("a").join("..").join("b.obj");
        let mut set = WatchSet::default();
        set.set_paths(vec![dotted.clone()]);
        let write = event(EventKind::Modify(ModifyKind::Any), &[&root.join("b.obj")]);
        assert_eq!(set.classify(&write).changed, BTreeSet::from([dotted]));
    }

    #[cfg(unix)]
    #[test]
    fn a_symlinked_source_is_also_watched_at_its_target() {
        let tmp = tempfile::tempdir().unwrap();
        let root = fs::canonicalize(tmp.path()).unwrap();
        fs::create_dir(root.join("assets")).unwrap();
        fs::create_dir(root.join("scene")).unwrap();
        let target = root.join("assets").join("real.obj");
        fs::write(&target, "v 0 0 0").unwrap();
        let link = root.join("scene").join("link.obj");
        std::os::unix::fs::symlink(&target, &link).unwrap();
        let mut set = WatchSet::default();
        let mut backend = Recorder::default();
        set.set_paths(vec![link.clone()]);
        set.sync(&mut backend);
        assert_eq!(
            set.dirs(),
            &BTreeSet::from([root.join("assets"), root.join("scene")])
        );
        let write = event(EventKind::Modify(ModifyKind::Any), &[&target]);
        assert_eq!(set.classify(&write).changed, BTreeSet::from([link]));
    }
}

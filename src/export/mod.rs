//! Exports for renderers and game engines (issue 37): a bank's tile set with the layout
//! and hash rule that place it ([`tiles`]), and (feature `gpu`) its sampler in the
//! renderer's shading language (`shader`), each written as a directory that appears whole
//! or not at all ([`StagedDir`]).

#[cfg(feature = "gpu")]
pub mod shader;
pub mod tiles;

use std::path::{Path, PathBuf};

use crate::error::{Error, Result};

pub use tiles::{TileFormat, TileSet, export_tiles};

/// An output directory built under a temporary sibling name and renamed into place by
/// [`StagedDir::commit`]; dropped uncommitted (an error on the way), the temporary
/// directory is removed. The target must not exist, or be an empty directory.
#[derive(Debug)]
pub struct StagedDir {
    target: PathBuf,
    staging: PathBuf,
    committed: bool,
}

impl StagedDir {
    /// Checks `target` (named `option` in errors) and creates the staging directory.
    pub fn new(target: &Path, option: &str) -> Result<StagedDir> {
        match std::fs::metadata(target) {
            Ok(m) if !m.is_dir() => {
                return Err(Error::param(
                    option,
                    target.display(),
                    "a directory to create (it is an existing file)",
                ));
            }
            Ok(_) => {
                let mut entries = std::fs::read_dir(target).map_err(|e| Error::io(target, e))?;
                if entries.next().is_some() {
                    return Err(Error::param(
                        option,
                        target.display(),
                        "a new or empty directory (it has files; remove them or choose another)",
                    ));
                }
            }
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
            Err(e) => return Err(Error::io(target, e)),
        }
        let staging = crate::io::temp_sibling(target, &format!(".part-{}", std::process::id()));
        if staging.exists() {
            std::fs::remove_dir_all(&staging).map_err(|e| Error::io(&staging, e))?;
        }
        std::fs::create_dir_all(&staging).map_err(|e| Error::io(&staging, e))?;
        Ok(StagedDir {
            target: target.to_path_buf(),
            staging,
            committed: false,
        })
    }

    /// Where to write the file that will be `target/relative`.
    pub fn path(&self, relative: &str) -> PathBuf {
        self.staging.join(relative)
    }

    /// Moves the staged directory to the target.
    pub fn commit(mut self) -> Result<()> {
        if self.target.is_dir() {
            // Checked empty in `new`; remove_dir fails if something appeared since.
            std::fs::remove_dir(&self.target).map_err(|e| Error::io(&self.target, e))?;
        }
        std::fs::rename(&self.staging, &self.target).map_err(|e| Error::io(&self.target, e))?;
        self.committed = true;
        Ok(())
    }
}

impl Drop for StagedDir {
    fn drop(&mut self) {
        if !self.committed {
            let _ = std::fs::remove_dir_all(&self.staging);
        }
    }
}

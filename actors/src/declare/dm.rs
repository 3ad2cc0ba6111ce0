//! Datamanagers named by constants.
//!
//! An operation finds a datamanager by name (`ctx.dm("feature")`); a misspelt name is found
//! missing only when the operation runs. [`DmName`] lets the same calls take a constant
//! instead — the well-known [`WORLD`](marie_dm::WORLD), [`FEATURE`](marie_dm::FEATURE),
//! [`PARAMETER`](marie_dm::PARAMETER), or an embedder's own [`DmSpec`] — whose misspelling
//! the compiler catches. Strings keep working.

use marie_dm::DmSpec;

/// Something that names a datamanager: a [`DmSpec`] constant, or its name (or numeric id)
/// as text.
///
/// ```
/// use marie_actors::declare::DmName;
/// use marie_dm::{DmSpec, FEATURE};
///
/// const ODOMETRY: DmSpec = DmSpec::new("odometry", 1210);
/// fn name(dm: impl DmName) -> String { dm.dm_name().to_string() }
/// assert_eq!(name(FEATURE), "feature");
/// assert_eq!(name(ODOMETRY), "odometry");
/// assert_eq!(name("world"), "world");
/// assert_eq!(name(String::from("1203")), "1203");
/// ```
pub trait DmName {
    /// The name (or id) the registry knows the datamanager by.
    fn dm_name(&self) -> &str;
}

impl DmName for DmSpec {
    fn dm_name(&self) -> &str {
        self.name
    }
}

impl DmName for str {
    fn dm_name(&self) -> &str {
        self
    }
}

impl DmName for String {
    fn dm_name(&self) -> &str {
        self
    }
}

impl<T: DmName + ?Sized> DmName for &T {
    fn dm_name(&self) -> &str {
        (**self).dm_name()
    }
}

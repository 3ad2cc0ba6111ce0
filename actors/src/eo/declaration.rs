//! Checking what an operation declares — its identity, parameters and flags — before it
//! runs, so that a bad declaration is refused with a message naming the operation and the
//! problem (a node's builder checks every operation type at start; a host checks again when
//! it starts an instance).

use super::Operation;

/// What an operation declares about itself, read from one instance built for it
/// ([`OperationFactory::declared`](super::OperationFactory::declared)): what a check knows
/// of a version without starting it — `marie check` looks at the newer versions this build
/// knows this way.
#[derive(Clone, Debug, PartialEq)]
pub struct Declared {
    /// Name, id, version, description.
    pub identity: super::Identity,
    /// Its parameters.
    pub schema: marie_vocabulary::property::ParamSchema,
    /// Its flags.
    pub flags: Vec<marie_vocabulary::status::FlagDecl>,
    /// How its older versions' parameters map onto its own.
    pub migrations: crate::declare::Migrations,
}

impl Declared {
    /// What `op` declares.
    pub fn of<O: Operation>(op: &O) -> Self {
        Declared {
            identity: op.identity(),
            schema: op.parameters(),
            flags: op.flags(),
            migrations: op.migrations(),
        }
    }
}

/// Most flags an operation may declare: its status word has 32 bits.
pub const MAX_FLAGS: usize = 32;

/// What is wrong with an operation's declarations.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("operation `{operation}` (version {version}) declares {problems}", problems = .problems.join("; "))]
pub struct DeclarationError {
    /// The operation's name.
    pub operation: String,
    /// The version it declares.
    pub version: String,
    /// Each problem found.
    pub problems: Vec<String>,
}

/// Check `op`'s declarations: parameters whose defaults and ranges
/// agree and whose names differ ([`ParamSchema::self_check`](marie_vocabulary::property::ParamSchema::self_check)),
/// at most [`MAX_FLAGS`] flags with distinct names.
///
/// ```
/// use marie_actors::eo::{check_declaration, Identity, OpContext, OpError, Operation, Step};
/// use marie_vocabulary::property::{ParamDecl, ParamSchema};
///
/// struct Bad;
/// impl Operation for Bad {
///     fn identity(&self) -> Identity {
///         Identity::new("bad", 1, "1.0.0", "a default outside its range")
///     }
///     fn parameters(&self) -> ParamSchema {
///         ParamSchema::new(vec![ParamDecl::float("speed", 9.0).range(0.0, 2.0)])
///     }
///     async fn step(&mut self, _: &mut OpContext) -> Result<Step, OpError> {
///         Ok(Step::Continue)
///     }
/// }
/// let err = check_declaration(&Bad).unwrap_err();
/// assert_eq!(err.operation, "bad");
/// assert!(err.to_string().contains("speed"), "{err}");
/// ```
pub fn check_declaration<O: Operation>(op: &O) -> Result<(), DeclarationError> {
    let identity = op.identity();
    let mut problems = Vec::new();
    let schema = op.parameters();
    for p in schema.self_check() {
        problems.push(format!("a bad parameter: {p}"));
    }
    problems.extend(op.migrations().problems(&schema));
    let flags = op.flags();
    if flags.len() > MAX_FLAGS {
        problems.push(format!(
            "{} flags (at most {MAX_FLAGS}: the status word has 32 bits)",
            flags.len()
        ));
    }
    let mut seen = std::collections::BTreeSet::new();
    for f in &flags {
        if !seen.insert(f.name.as_str()) {
            problems.push(format!("flag `{}` twice", f.name));
        }
    }
    if problems.is_empty() {
        Ok(())
    } else {
        Err(DeclarationError {
            operation: identity.name.to_string(),
            version: identity.version.to_string(),
            problems,
        })
    }
}

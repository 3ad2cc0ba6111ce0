//! What [`Node::run`](super::Node::run) takes: a mission in any of the forms an application
//! holds one — a file's text, a mission built in code, a parsed or an already checked one.

use super::{Node, NodeError};
use marie_actors::dispatcher::mission::{Mission, MissionBuilder, ParsedMission};

/// A mission to run, checked against the running instances (unless it already was) before
/// it runs.
#[derive(Clone, Debug)]
pub enum MissionInput {
    /// A mission file's text (TOML).
    Text(String),
    /// Built in code.
    Built(MissionBuilder),
    /// Parsed, not yet checked against what runs.
    Parsed(ParsedMission),
    /// Checked: it runs as it is, with the choices its check made
    /// ([`Mission::checked`]): the dispatcher binds them unless an instance changed since.
    Checked(Mission),
}

impl From<&str> for MissionInput {
    fn from(text: &str) -> Self {
        MissionInput::Text(text.to_string())
    }
}

impl From<String> for MissionInput {
    fn from(text: String) -> Self {
        MissionInput::Text(text)
    }
}

impl From<MissionBuilder> for MissionInput {
    fn from(b: MissionBuilder) -> Self {
        MissionInput::Built(b)
    }
}

impl From<ParsedMission> for MissionInput {
    fn from(p: ParsedMission) -> Self {
        MissionInput::Parsed(p)
    }
}

impl From<Mission> for MissionInput {
    fn from(m: Mission) -> Self {
        MissionInput::Checked(m)
    }
}

impl Node {
    /// The mission `input` stands for, checked against the running instances — carrying
    /// the check's choices, so that the run selects once.
    pub(super) async fn resolve(&self, input: MissionInput) -> Result<Mission, NodeError> {
        let parsed = match input {
            MissionInput::Checked(m) => return Ok(m),
            MissionInput::Text(text) => {
                ParsedMission::parse(&text, None).map_err(NodeError::Mission)?
            }
            MissionInput::Built(b) => b.build().map_err(NodeError::Mission)?,
            MissionInput::Parsed(p) => p,
        };
        self.check_mission(&parsed).await
    }
}

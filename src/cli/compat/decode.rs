//! Decode a sample as a node of this build does, and encode what it decoded again.

use super::corpus::Entry;
use super::samples::Form;
use marie::cluster::net::heartbeat::BeatMsg;
use marie::cluster::node::desk::DeskMsg;
use marie::cluster::relay::WatcherMsg;
use marie::cluster::replicas::HostMsg;
use marie::dispatcher::DispatcherMsg;
use marie::dm::{DmMsg, NewRecord};
use marie::eo::EoMsg;
use marie::events::Event;
use marie::fence::FenceMsg;
use marie::provision::ProvisionMsg;
use marie::wire::Envelope;
use marie_missions::hardware::CartMsg;
use ractor::message::SerializedMessage;
use ractor::{Message, RpcReplyPort};
use std::time::Duration;

/// Decode `bytes` as `entry` says through the node's own path, and encode the value again
/// with this build: the bytes this build would send in its stead.
pub(crate) fn redo(entry: &Entry, bytes: &[u8]) -> Result<Vec<u8>, String> {
    match entry.ty.as_str() {
        "EoMsg" => message::<EoMsg>(entry, bytes),
        "ProvisionMsg" => message::<ProvisionMsg>(entry, bytes),
        "DispatcherMsg" => message::<DispatcherMsg>(entry, bytes),
        "FenceMsg" => message::<FenceMsg>(entry, bytes),
        "CartMsg" => message::<CartMsg>(entry, bytes),
        "DmMsg" => message::<DmMsg>(entry, bytes),
        "DeskMsg" => message::<DeskMsg>(entry, bytes),
        "BeatMsg" => message::<BeatMsg>(entry, bytes),
        "HostMsg" => message::<HostMsg>(entry, bytes),
        "WatcherMsg" => message::<WatcherMsg>(entry, bytes),
        "Event" => event(bytes),
        "NewRecord" => value::<NewRecord>(bytes),
        other => Err(format!("this build knows no type `{other}`")),
    }
}

/// A message variant through ractor's `Message::deserialize` (what a node's session does
/// with a frame), then `Message::serialize`.
fn message<M: Message>(entry: &Entry, bytes: &[u8]) -> Result<Vec<u8>, String> {
    let variant = entry.variant.clone();
    let args = bytes.to_vec();
    let frame = match entry.form {
        Form::Cast => SerializedMessage::Cast {
            variant,
            args,
            metadata: None,
        },
        Form::Call => {
            let (tx, _rx) = ractor::concurrency::oneshot::<Vec<u8>>();
            SerializedMessage::Call {
                variant,
                args,
                reply: RpcReplyPort::from((tx, Duration::from_secs(5))),
                metadata: None,
            }
        }
        other => return Err(format!("a message cannot be a sample of form {other:?}")),
    };
    let decoded = M::deserialize(frame).map_err(|_| {
        "does not decode with this build (an unknown variant, a field missing or of another \
         type)"
            .to_string()
    })?;
    match decoded.serialize() {
        Ok(SerializedMessage::Cast { args, .. }) => Ok(args),
        Ok(SerializedMessage::Call { args, .. }) => Ok(args),
        _ => Err("decodes, but this build does not encode it again".into()),
    }
}

/// An event frame as a watcher reads it: the envelope (its version checked), then the
/// event; encoded again as this build sends it to a watcher of the frame's version (the
/// event as that version defines it, `Event::spoken_at`).
fn event(bytes: &[u8]) -> Result<Vec<u8>, String> {
    let env = Envelope::from_bytes(bytes).map_err(|e| e.to_string())?;
    let event: Event = env.payload().map_err(|e| e.to_string())?;
    Envelope::at(env.version, &env.kind, &*event.spoken_at(env.version))
        .and_then(|e| e.to_bytes())
        .map_err(|e| e.to_string())
}

/// A value through `wire::decode` and `wire::encode`.
fn value<T: serde::de::DeserializeOwned + serde::Serialize>(
    bytes: &[u8],
) -> Result<Vec<u8>, String> {
    let v: T = marie::wire::decode(bytes).map_err(|e| format!("does not decode: {e}"))?;
    marie::wire::encode(&v).map_err(|e| format!("does not encode again: {e}"))
}

//! Clear errors for clients beyond a service's capacity. The daemon fixes every service's
//! capacity when it creates it (`MAX_SUBSCRIBERS` subscribers per publish–subscribe service,
//! `CONTROL_MAX_CLIENTS` control clients); one client too many is refused by iceoryx2 in the
//! client's own process, so the daemon notices nothing.

use iceoryx2::port::subscriber::SubscriberCreateError;

use crate::services::{IpcError, MAX_SUBSCRIBERS};

/// The error for a subscriber `service` refused, naming the limit when that is the reason.
pub fn subscriber_create_error(service: &str, e: SubscriberCreateError) -> IpcError {
    match e {
        SubscriberCreateError::ExceedsMaxSupportedSubscribers => IpcError::Full {
            service: service.to_string(),
            port: "subscriber",
            limit: MAX_SUBSCRIBERS,
            constant: "MAX_SUBSCRIBERS",
        },
        other => IpcError::Iceoryx {
            what: "create subscriber for",
            service: service.to_string(),
            reason: format!("{other:?}"),
        },
    }
}

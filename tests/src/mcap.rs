//! A reader of MCAP files (what `armor-mod-recorder` writes) made from nothing but the MCAP
//! specification, independently of the crate the recorder writes with. It reads files whose
//! chunks are not compressed: the tests record with the recorder's `compression=none`.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// One message of a channel: its log time (ns) and data.
pub type Message = (u64, Vec<u8>);

/// The messages of every channel of an MCAP file whose chunks are not compressed, by (topic,
/// message encoding), each channel's in file order.
pub fn read_mcap(file: &Path) -> HashMap<(String, String), Vec<Message>> {
    const MAGIC: &[u8] = b"\x89MCAP0\r\n";
    let bytes =
        std::fs::read(file).unwrap_or_else(|err| panic!("cannot read {}: {err}", file.display()));
    assert!(
        bytes.len() >= 2 * MAGIC.len() && bytes.starts_with(MAGIC) && bytes.ends_with(MAGIC),
        "{} is not a complete MCAP file",
        file.display()
    );
    let mut channels: HashMap<u16, (String, String)> = HashMap::new();
    let mut messages: Vec<(u16, Message)> = Vec::new();
    read_records(
        &bytes[MAGIC.len()..bytes.len() - MAGIC.len()],
        &mut channels,
        &mut messages,
    );
    let mut by_channel: HashMap<(String, String), Vec<Message>> = HashMap::new();
    for (channel, message) in messages {
        let key = channels[&channel].clone();
        by_channel.entry(key).or_default().push(message);
    }
    by_channel
}

/// The `N` of a recorder's `recorded N messages` line.
pub fn recorded(line: &str) -> Option<u64> {
    let rest = &line[line.find("recorded ")? + "recorded ".len()..];
    rest.split_whitespace().next()?.parse().ok()
}

/// The files a recorder wrote for `file` over a run: `NAME.EXT`, then `NAME-2.EXT`,
/// `NAME-3.EXT`, … (it starts a new one each time it is started again), those that exist, in
/// that order.
pub fn recorder_segments(file: &Path) -> Vec<PathBuf> {
    let stem = file.file_stem().unwrap().to_string_lossy().into_owned();
    let ext = file
        .extension()
        .map(|ext| format!(".{}", ext.to_string_lossy()))
        .unwrap_or_default();
    let mut segments = Vec::new();
    if file.exists() {
        segments.push(file.to_path_buf());
    }
    for n in 2.. {
        let segment = file.with_file_name(format!("{stem}-{n}{ext}"));
        if !segment.exists() {
            break;
        }
        segments.push(segment);
    }
    segments
}

struct Cursor<'a>(&'a [u8]);

impl<'a> Cursor<'a> {
    fn take(&mut self, n: usize) -> &'a [u8] {
        assert!(n <= self.0.len(), "an MCAP record runs past its end");
        let (head, rest) = self.0.split_at(n);
        self.0 = rest;
        head
    }
    fn u16(&mut self) -> u16 {
        u16::from_le_bytes(self.take(2).try_into().unwrap())
    }
    fn u32(&mut self) -> u32 {
        u32::from_le_bytes(self.take(4).try_into().unwrap())
    }
    fn u64(&mut self) -> u64 {
        u64::from_le_bytes(self.take(8).try_into().unwrap())
    }
    fn string(&mut self) -> String {
        let len = self.u32() as usize;
        String::from_utf8(self.take(len).to_vec()).unwrap()
    }
}

fn read_records(
    bytes: &[u8],
    channels: &mut HashMap<u16, (String, String)>,
    messages: &mut Vec<(u16, Message)>,
) {
    let mut records = Cursor(bytes);
    while !records.0.is_empty() {
        let opcode = records.take(1)[0];
        let len = records.u64() as usize;
        let mut body = Cursor(records.take(len));
        match opcode {
            // Channel: id, schema id, topic, message encoding, metadata.
            0x04 => {
                let id = body.u16();
                body.u16();
                let topic = body.string();
                let encoding = body.string();
                channels.insert(id, (topic, encoding));
            }
            // Message: channel id, sequence, log time, publish time, data.
            0x05 => {
                let channel = body.u16();
                body.u32();
                let log_time = body.u64();
                body.u64();
                messages.push((channel, (log_time, body.0.to_vec())));
            }
            // Chunk: start and end times, size and CRC, compression, records.
            0x06 => {
                body.take(8 + 8 + 8 + 4);
                let compression = body.string();
                assert_eq!(
                    compression, "",
                    "the tests record without compression (the recorder's compression=none)"
                );
                let len = body.u64() as usize;
                read_records(body.take(len), channels, messages);
            }
            _ => {}
        }
    }
}

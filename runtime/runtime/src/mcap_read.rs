//! The records of an MCAP file that [`crate::replay`] reads, from bytes no one vouches for:
//! framing (opcode, 64-bit length, body) in the file and in its chunks (stored, zstd or lz4), and
//! the schema, channel and message records (the MCAP specification's layouts). Every length is
//! checked against the bytes there before anything is allocated, and a chunk is decompressed
//! only as far as it may take.
//!
//! The mcap crate still writes recordings (the recorder), but its reader is not used on them: its
//! record parser reserves the length a string announces (up to 4 GiB) before it finds the record
//! shorter, and a record longer than the rest of its chunk overflows a subtraction in its chunk
//! reader (a panic in a debug build). The fuzz target `recording` found both.

use std::collections::BTreeMap;
use std::io::Read as _;

use anyhow::{Context as _, bail};

const SCHEMA: u8 = 0x03;
const CHANNEL: u8 = 0x04;
const MESSAGE: u8 = 0x05;
const CHUNK: u8 = 0x06;
const DATA_END: u8 = 0x0F;
const FOOTER: u8 = 0x02;

/// A chunk that would take more than the reader may once decompressed.
#[derive(Debug, thiserror::Error)]
#[error("a chunk of {size_bytes} bytes once decompressed, more than the {max_bytes} it may take")]
pub(crate) struct ChunkTooLarge {
    pub size_bytes: u64,
    pub max_bytes: usize,
}

/// What a record says, of what a reader of messages needs.
#[derive(Debug, PartialEq)]
pub(crate) enum Record {
    Schema {
        id: u16,
        name: String,
    },
    Channel(ChannelRecord),
    Message {
        channel_id: u16,
        log_time_ns: u64,
        data: Vec<u8>,
    },
    /// The end of the data section (the summary, which repeats schemas and channels, follows).
    DataEnd,
    /// Any other record, not read.
    Other,
}

#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) struct ChannelRecord {
    pub id: u16,
    /// 0 for none.
    pub schema_id: u16,
    pub topic: String,
    pub message_encoding: String,
    pub metadata: BTreeMap<String, String>,
}

/// The records of a file, in order, those of each chunk in its place. Ends after the first error.
pub(crate) struct Records<'a> {
    /// The file's records not read yet.
    file: &'a [u8],
    /// The records of the chunk being read, and where.
    chunk: Option<(Vec<u8>, usize)>,
    /// The most a chunk may take once decompressed.
    max_chunk_bytes: usize,
    failed: bool,
}

impl<'a> Records<'a> {
    /// The records of `file` (which must start with the MCAP magic), refusing a chunk that
    /// decompresses to more than `max_chunk_bytes`.
    pub fn new(file: &'a [u8], max_chunk_bytes: usize) -> anyhow::Result<Records<'a>> {
        let Some(records) = file.strip_prefix(mcap::MAGIC) else {
            bail!("no MCAP magic at its start");
        };
        Ok(Records {
            file: records,
            chunk: None,
            max_chunk_bytes,
            failed: false,
        })
    }

    fn next_record(&mut self) -> anyhow::Result<Option<Record>> {
        loop {
            if let Some((records, at)) = &mut self.chunk {
                if *at < records.len() {
                    let (opcode, body, used) = frame(&records[*at..]).context("in a chunk")?;
                    *at += used;
                    // The data section ends in the file, not in a chunk.
                    if opcode == DATA_END || opcode == CHUNK {
                        bail!("a record of opcode {opcode:#04x} in a chunk");
                    }
                    return read_record(opcode, body).map(Some);
                }
                self.chunk = None;
            }
            if self.file.is_empty() {
                return Ok(None);
            }
            let (opcode, body, used) = frame(self.file)?;
            self.file = &self.file[used..];
            if opcode == FOOTER {
                // Only the end magic follows.
                self.file = &[];
            }
            if opcode == CHUNK {
                self.chunk = Some((chunk_records(body, self.max_chunk_bytes)?, 0));
                continue;
            }
            return read_record(opcode, body).map(Some);
        }
    }
}

impl Iterator for Records<'_> {
    type Item = anyhow::Result<Record>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.failed {
            return None;
        }
        let next = self.next_record().transpose();
        self.failed = matches!(next, Some(Err(_)));
        next
    }
}

/// The opcode and body of the record `bytes` start with, and the bytes it takes.
fn frame(bytes: &[u8]) -> anyhow::Result<(u8, &[u8], usize)> {
    let mut fields = Fields(bytes);
    let (Some([opcode]), Some(len)) = (fields.array::<1>(), fields.u64()) else {
        bail!("a record cut short in its opcode or length");
    };
    let body = usize::try_from(len)
        .ok()
        .and_then(|len| fields.take(len))
        .with_context(|| {
            format!(
                "a record (opcode {opcode:#04x}) of {len} bytes, where {} are left",
                fields.0.len()
            )
        })?;
    Ok((opcode, body, bytes.len() - fields.0.len()))
}

/// The records a chunk holds, decompressed.
fn chunk_records(body: &[u8], max_bytes: usize) -> anyhow::Result<Vec<u8>> {
    let mut fields = Fields(body);
    let header = (|| {
        let _message_start_time = fields.u64()?;
        let _message_end_time = fields.u64()?;
        let uncompressed_size = fields.u64()?;
        let _uncompressed_crc = fields.u32()?;
        let compression = fields.string()?;
        let len = usize::try_from(fields.u64()?).ok()?;
        Some((uncompressed_size, compression, fields.take(len)?))
    })();
    let Some((uncompressed_size, compression, records)) = header else {
        bail!("a damaged chunk header ({} bytes)", body.len());
    };
    let size = usize::try_from(uncompressed_size)
        .ok()
        .filter(|&size| size <= max_bytes)
        .ok_or(ChunkTooLarge {
            size_bytes: uncompressed_size,
            max_bytes,
        })?;
    // Read one byte beyond the size said, to tell a chunk that holds more from one that does
    // not; the decoders grow the buffer as they go, never to the size the header claims.
    let limit = u64::try_from(size).unwrap_or(u64::MAX).saturating_add(1);
    let mut out = Vec::new();
    match compression.as_str() {
        "" => out.extend_from_slice(records),
        "zstd" => {
            zstd::stream::read::Decoder::new(records)
                .and_then(|decoder| decoder.take(limit).read_to_end(&mut out))
                .context("a zstd chunk that does not decompress")?;
        }
        "lz4" => {
            lz4::Decoder::new(records)
                .and_then(|decoder| decoder.take(limit).read_to_end(&mut out))
                .context("an lz4 chunk that does not decompress")?;
        }
        other => bail!("a chunk compressed with `{other}` (zstd and lz4 are read)"),
    }
    if out.len() != size {
        bail!(
            "a chunk of {} bytes decompressed where its header says {size}",
            if out.len() > size {
                "more".to_owned()
            } else {
                out.len().to_string()
            }
        );
    }
    Ok(out)
}

/// Parses a schema, channel or message record. Other records are not read.
fn read_record(opcode: u8, body: &[u8]) -> anyhow::Result<Record> {
    let mut fields = Fields(body);
    let record = match opcode {
        SCHEMA => (|| {
            let id = fields.u16()?;
            let name = fields.string()?;
            Some(Record::Schema { id, name })
        })(),
        CHANNEL => (|| {
            Some(Record::Channel(ChannelRecord {
                id: fields.u16()?,
                schema_id: fields.u16()?,
                topic: fields.string()?,
                message_encoding: fields.string()?,
                metadata: fields.string_map()?,
            }))
        })(),
        MESSAGE => (|| {
            let channel_id = fields.u16()?;
            let _sequence = fields.u32()?;
            let log_time_ns = fields.u64()?;
            let _publish_time_ns = fields.u64()?;
            Some(Record::Message {
                channel_id,
                log_time_ns,
                data: fields.0.to_vec(),
            })
        })(),
        DATA_END => Some(Record::DataEnd),
        _ => Some(Record::Other),
    };
    record.with_context(|| {
        format!(
            "a damaged record (opcode {opcode:#04x}, {} bytes)",
            body.len()
        )
    })
}

/// The fields of a record not read yet, little-endian as MCAP writes them.
struct Fields<'a>(&'a [u8]);

impl<'a> Fields<'a> {
    fn take(&mut self, len: usize) -> Option<&'a [u8]> {
        let (taken, rest) = self.0.split_at_checked(len)?;
        self.0 = rest;
        Some(taken)
    }

    fn array<const N: usize>(&mut self) -> Option<[u8; N]> {
        self.take(N)?.try_into().ok()
    }

    fn u16(&mut self) -> Option<u16> {
        self.array().map(u16::from_le_bytes)
    }

    fn u32(&mut self) -> Option<u32> {
        self.array().map(u32::from_le_bytes)
    }

    fn u64(&mut self) -> Option<u64> {
        self.array().map(u64::from_le_bytes)
    }

    /// A string: its length in bytes (u32), then UTF-8.
    fn string(&mut self) -> Option<String> {
        let len = usize::try_from(self.u32()?).ok()?;
        let bytes = self.take(len)?;
        std::str::from_utf8(bytes).ok().map(str::to_owned)
    }

    /// A map of strings: its length in bytes (u32), then key and value strings.
    fn string_map(&mut self) -> Option<BTreeMap<String, String>> {
        let len = usize::try_from(self.u32()?).ok()?;
        let mut entries = Fields(self.take(len)?);
        let mut map = BTreeMap::new();
        while !entries.0.is_empty() {
            let key = entries.string()?;
            let value = entries.string()?;
            map.insert(key, value);
        }
        Some(map)
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]

    use std::io::Cursor;

    use super::*;

    /// A record as MCAP frames it: opcode, length (u64), body.
    fn record(opcode: u8, body: &[u8]) -> Vec<u8> {
        let mut out = vec![opcode];
        out.extend((body.len() as u64).to_le_bytes());
        out.extend(body);
        out
    }

    fn string(text: &str) -> Vec<u8> {
        let mut out = (text.len() as u32).to_le_bytes().to_vec();
        out.extend(text.as_bytes());
        out
    }

    fn read_all(file: &[u8], max_chunk_bytes: usize) -> anyhow::Result<Vec<Record>> {
        Records::new(file, max_chunk_bytes)?.collect()
    }

    fn messages(records: &[Record]) -> Vec<(u64, &[u8])> {
        records
            .iter()
            .filter_map(|record| match record {
                Record::Message {
                    log_time_ns, data, ..
                } => Some((*log_time_ns, data.as_slice())),
                _ => None,
            })
            .collect()
    }

    /// A recording written by the mcap crate, as the recorder writes them.
    fn written(compression: Option<mcap::Compression>, payload: &[u8]) -> Vec<u8> {
        let mut writer = mcap::WriteOptions::new()
            .compression(compression)
            .create(Cursor::new(Vec::new()))
            .unwrap();
        let schema = writer.add_schema("Counter", "", &[]).unwrap();
        let metadata = BTreeMap::from([("armor.data_type".to_owned(), "Counter".to_owned())]);
        let channel = writer
            .add_channel(schema, "counter.count", "postcard", &metadata)
            .unwrap();
        for log_time in [5, 7] {
            let header = mcap::records::MessageHeader {
                channel_id: channel,
                sequence: 1,
                log_time,
                publish_time: log_time,
            };
            writer.write_to_known_channel(&header, payload).unwrap();
        }
        writer.finish().unwrap();
        writer.into_inner().into_inner()
    }

    #[test]
    fn files_of_the_mcap_writer_are_read_whatever_their_compression() {
        let payload = vec![42; 3000];
        for compression in [
            None,
            Some(mcap::Compression::Zstd),
            Some(mcap::Compression::Lz4),
        ] {
            let records = read_all(&written(compression, &payload), usize::MAX).unwrap();
            assert!(records.contains(&Record::Schema {
                id: 1,
                name: "Counter".into()
            }));
            let channel = records.iter().find_map(|record| match record {
                Record::Channel(channel) => Some(channel.clone()),
                _ => None,
            });
            assert_eq!(
                channel,
                Some(ChannelRecord {
                    id: 1,
                    schema_id: 1,
                    topic: "counter.count".into(),
                    message_encoding: "postcard".into(),
                    metadata: BTreeMap::from([("armor.data_type".into(), "Counter".into())]),
                }),
                "{compression:?}"
            );
            assert_eq!(
                messages(&records),
                [(5, payload.as_slice()), (7, payload.as_slice())]
            );
            assert!(records.contains(&Record::DataEnd));
        }
    }

    #[test]
    fn a_chunk_larger_than_allowed_is_refused_before_it_is_decompressed() {
        let file = written(Some(mcap::Compression::Zstd), &[42; 3000]);
        let err = read_all(&file, 1000).unwrap_err().to_string();
        assert!(err.contains("more than the 1000 it may take"), "{err}");
    }

    #[test]
    fn hostile_lengths_are_refused_before_they_are_allocated() {
        // A channel whose topic claims 4 GiB, three bytes there: the mcap crate's parser
        // reserved the 4 GiB first.
        let mut channel = vec![1, 0, 0, 0];
        channel.extend(u32::MAX.to_le_bytes());
        channel.extend(b"abc");
        let file = [mcap::MAGIC.to_vec(), record(CHANNEL, &channel)].concat();
        let err = read_all(&file, usize::MAX).unwrap_err().to_string();
        assert!(err.contains("a damaged record (opcode 0x04"), "{err}");

        // A record announcing 2^64 − 1 bytes.
        let mut huge = mcap::MAGIC.to_vec();
        huge.push(MESSAGE);
        huge.extend(u64::MAX.to_le_bytes());
        let err = read_all(&huge, usize::MAX).unwrap_err().to_string();
        assert!(
            err.contains("of 18446744073709551615 bytes, where 0 are left"),
            "{err}"
        );

        // A stored chunk whose record is longer than the chunk: the mcap crate's chunk reader
        // subtracted its length from what was left.
        let mut cut = [record(MESSAGE, &[0; 22]), vec![MESSAGE]].concat();
        cut.extend(100_u64.to_le_bytes());
        let mut chunk = Vec::new();
        chunk.extend([0; 16]);
        chunk.extend((cut.len() as u64).to_le_bytes());
        chunk.extend([0; 4]);
        chunk.extend(string(""));
        chunk.extend((cut.len() as u64).to_le_bytes());
        chunk.extend(&cut);
        let file = [mcap::MAGIC.to_vec(), record(CHUNK, &chunk)].concat();
        let mut records = Records::new(&file, usize::MAX).unwrap();
        assert!(matches!(records.next(), Some(Ok(Record::Message { .. }))));
        let err = records.next().unwrap().unwrap_err();
        assert!(
            format!("{err:#}").contains("in a chunk: a record"),
            "{err:#}"
        );
        assert!(records.next().is_none(), "nothing after an error");

        // A chunk saying it holds more (or less) than it does.
        let mut lying = chunk.clone();
        lying[16..24].copy_from_slice(&(cut.len() as u64 + 1).to_le_bytes());
        let file = [mcap::MAGIC.to_vec(), record(CHUNK, &lying)].concat();
        let err = read_all(&file, usize::MAX).unwrap_err().to_string();
        assert!(err.contains("decompressed where its header says"), "{err}");

        let mut map = Fields(&[9, 0, 0, 0, 1, 0, 0, 0, b'k', 5, 0, 0, 0]);
        assert_eq!(map.string_map(), None, "a value longer than the map");
        assert!(Records::new(b"not mcap", 1).is_err());
    }
}

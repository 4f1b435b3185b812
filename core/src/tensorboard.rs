//! TensorBoard event files: every metric a run logs, as scalars that `tensorboard --logdir`
//! shows (legged_gym/rsl_rl users look there for reward terms, losses and the curriculum).
//!
//! The file is TensorFlow's record format: each record is its length (u64, little endian),
//! the masked CRC-32C of the length, the bytes of one `Event` protobuf, and their masked
//! CRC-32C. The first event names the file version. Only the messages and fields a scalar
//! needs are declared here (`tensorflow/core/util/event.proto`, `summary.proto`).

use std::fs::{File, OpenOptions};
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::time::{SystemTime, UNIX_EPOCH};

use prost::Message;

use std::io::Result;

/// `tensorflow.Event`, the fields a scalar log uses.
#[derive(Clone, PartialEq, prost::Message)]
struct Event {
    /// Seconds since the epoch.
    #[prost(double, tag = "1")]
    wall_time: f64,
    /// Global step (the training epoch).
    #[prost(int64, tag = "2")]
    step: i64,
    /// `brain.Event:2` in the first event of a file.
    #[prost(string, optional, tag = "3")]
    file_version: Option<String>,
    /// The values of this step.
    #[prost(message, optional, tag = "5")]
    summary: Option<Summary>,
}

/// `tensorflow.Summary`.
#[derive(Clone, PartialEq, prost::Message)]
struct Summary {
    #[prost(message, repeated, tag = "1")]
    value: Vec<SummaryValue>,
}

/// `tensorflow.Summary.Value` holding a `simple_value`.
#[derive(Clone, PartialEq, prost::Message)]
struct SummaryValue {
    #[prost(string, tag = "1")]
    tag: String,
    #[prost(float, optional, tag = "2")]
    simple_value: Option<f32>,
}

fn masked_crc(bytes: &[u8]) -> u32 {
    let c = crc32c::crc32c(bytes);
    c.rotate_right(15).wrapping_add(0xa282_ead8)
}

/// Appends scalar events to one `events.out.tfevents.*` file in a directory.
pub struct EventWriter {
    out: BufWriter<File>,
    path: PathBuf,
}

impl EventWriter {
    /// Starts a new event file in `dir` (created if missing). A resumed run starts another
    /// file in the same directory; TensorBoard reads them all as one run.
    pub fn create(dir: &Path) -> Result<EventWriter> {
        std::fs::create_dir_all(dir)?;
        let now = SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .unwrap_or_default();
        let host = std::fs::read_to_string("/etc/hostname")
            .map(|h| h.trim().to_string())
            .ok()
            .filter(|h| !h.is_empty() && !h.contains('/'))
            .unwrap_or_else(|| "localhost".into());
        let path = dir.join(format!(
            "events.out.tfevents.{}.{host}.{}",
            now.as_secs(),
            std::process::id()
        ));
        let file = OpenOptions::new().create(true).append(true).open(&path)?;
        let mut w = EventWriter {
            out: BufWriter::new(file),
            path,
        };
        w.write(&Event {
            wall_time: now.as_secs_f64(),
            step: 0,
            file_version: Some("brain.Event:2".into()),
            summary: None,
        })?;
        w.flush()?;
        Ok(w)
    }

    /// The event file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Writes one step's scalars (non-finite values are written as they are: TensorBoard
    /// shows them as such).
    pub fn scalars<'a>(
        &mut self,
        step: u32,
        values: impl IntoIterator<Item = (&'a str, f64)>,
    ) -> Result<()> {
        let value = values
            .into_iter()
            .map(|(tag, v)| SummaryValue {
                tag: tag.to_string(),
                simple_value: Some(v as f32),
            })
            .collect();
        let wall_time = SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .unwrap_or_default()
            .as_secs_f64();
        self.write(&Event {
            wall_time,
            step: i64::from(step),
            file_version: None,
            summary: Some(Summary { value }),
        })
    }

    /// Flushes buffered events to the file.
    pub fn flush(&mut self) -> Result<()> {
        self.out.flush()
    }

    fn write(&mut self, e: &Event) -> Result<()> {
        let data = e.encode_to_vec();
        let len = (data.len() as u64).to_le_bytes();
        self.out.write_all(&len)?;
        self.out.write_all(&masked_crc(&len).to_le_bytes())?;
        self.out.write_all(&data)?;
        self.out.write_all(&masked_crc(&data).to_le_bytes())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Reads the records back with their checksums (the format TensorBoard reads).
    fn records(path: &Path) -> Vec<Vec<u8>> {
        let b = std::fs::read(path).unwrap();
        let mut out = Vec::new();
        let mut i = 0;
        while i < b.len() {
            let len_bytes = &b[i..i + 8];
            let len = u64::from_le_bytes(len_bytes.try_into().unwrap()) as usize;
            let crc = u32::from_le_bytes(b[i + 8..i + 12].try_into().unwrap());
            assert_eq!(crc, masked_crc(len_bytes));
            let data = &b[i + 12..i + 12 + len];
            let crc = u32::from_le_bytes(b[i + 12 + len..i + 16 + len].try_into().unwrap());
            assert_eq!(crc, masked_crc(data));
            out.push(data.to_vec());
            i += 16 + len;
        }
        out
    }

    #[test]
    fn the_crc_is_tensorflows_masked_crc32c() {
        // CRC-32C of "123456789" is 0xE3069283 (the standard check value).
        assert_eq!(crc32c::crc32c(b"123456789"), 0xE306_9283);
        assert_eq!(
            masked_crc(b""),
            0u32.rotate_right(15).wrapping_add(0xa282_ead8)
        );
    }

    #[test]
    fn scalars_round_trip_through_the_record_format() {
        let dir = tempfile::tempdir().unwrap();
        let mut w = EventWriter::create(dir.path()).unwrap();
        w.scalars(3, [("loss/value", 0.5), ("reward/torques", -0.25)])
            .unwrap();
        w.flush().unwrap();
        let recs = records(w.path());
        assert_eq!(recs.len(), 2);
        let first = Event::decode(recs[0].as_slice()).unwrap();
        assert_eq!(first.file_version.as_deref(), Some("brain.Event:2"));
        let e = Event::decode(recs[1].as_slice()).unwrap();
        assert_eq!(e.step, 3);
        let v = e.summary.unwrap().value;
        assert_eq!(v[1].tag, "reward/torques");
        assert_eq!(v[1].simple_value, Some(-0.25));
    }
}

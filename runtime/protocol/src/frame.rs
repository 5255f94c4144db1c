//! Reading one frame of a bounded length, for both ends of the link: the run bounds a request
//! far below the wire's own limit.

use armor_module_api::wire::WireError;
use armor_module_api::wire::blocking;

/// Reads one frame of at most `limit` bytes and decodes its message.
pub fn read_bounded<T: serde::de::DeserializeOwned>(
    reader: &mut impl std::io::Read,
    limit: usize,
) -> Result<T, WireError> {
    let mut header = [0; 4];
    read_exact(reader, &mut header)?;
    let len = u32::from_le_bytes(header) as usize;
    if len > limit {
        return Err(WireError::FrameTooLarge(len));
    }
    let mut frame = header.to_vec();
    frame.resize(4 + len, 0);
    read_exact(reader, &mut frame[4..])?;
    blocking::read_message(&mut frame.as_slice())
}

fn read_exact(reader: &mut impl std::io::Read, buf: &mut [u8]) -> Result<(), WireError> {
    reader.read_exact(buf).map_err(|err| match err.kind() {
        std::io::ErrorKind::UnexpectedEof => WireError::Closed,
        _ => WireError::Io(err),
    })
}

/// Whether the peer closed (or reset) the connection.
pub fn closed(err: &WireError) -> bool {
    match err {
        WireError::Closed => true,
        WireError::Io(err) => matches!(
            err.kind(),
            std::io::ErrorKind::ConnectionReset | std::io::ErrorKind::BrokenPipe
        ),
        _ => false,
    }
}

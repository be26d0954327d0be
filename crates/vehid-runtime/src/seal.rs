//! The pickles' integrity check: every saved state is postcard followed by a CRC-32 of its
//! bytes (postcard's CRC flavour; CRC-32C, the Castagnoli polynomial of iSCSI and ext4), read
//! back only when the checksum matches and no byte follows. A flipped, cut or appended byte
//! is then an error, not a different state that happens to decode: a random change passes
//! with probability 2⁻³². (What a checksum cannot catch, a state written with a valid
//! checksum over invalid values, the core's `restored` checks refuse.)

use serde::{Deserialize, Serialize};

/// Why sealed bytes were not opened (or a value not sealed): postcard's error.
pub use postcard::Error;

static CRC: crc::Crc<u32> = crc::Crc::<u32>::new(&crc::CRC_32_ISCSI);

/// `value` as postcard bytes with their CRC-32 appended.
pub fn seal<T: Serialize + ?Sized>(value: &T) -> Result<Vec<u8>, postcard::Error> {
    postcard::to_allocvec_crc32(value, CRC.digest())
}

/// The value of sealed `bytes`: an error when the checksum does not match, the bytes do not
/// decode, or bytes are left over.
pub fn open<'a, T: Deserialize<'a>>(bytes: &'a [u8]) -> Result<T, postcard::Error> {
    let (value, rest) = postcard::take_from_bytes_crc32(bytes, CRC.digest())?;
    if rest.is_empty() {
        Ok(value)
    } else {
        Err(postcard::Error::DeserializeBadEncoding)
    }
}

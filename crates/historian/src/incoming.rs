//! One message as it came from Zenoh (or from a daemon's recent history), before it is
//! parsed: what it is, its key and its bytes. The buffer holds these, the spill stores them.

/// What a message is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum Kind {
    Health = 1,
    Status = 2,
}

impl Kind {
    pub fn from_u8(v: u8) -> Kind {
        if v == 2 {
            Kind::Status
        } else {
            Kind::Health
        }
    }
}

/// One message as it came from Zenoh (or from a daemon's recent history).
#[derive(Debug, Clone)]
pub struct Incoming {
    pub kind: Kind,
    pub key: String,
    pub payload: Vec<u8>,
    /// Fetched to fill a gap (not live).
    pub recovered: bool,
}

impl Incoming {
    /// Bytes it holds (key and payload), as the buffer counts them.
    pub fn size(&self) -> u64 {
        (self.key.len() + self.payload.len()) as u64
    }
}

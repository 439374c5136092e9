//! Job keys: 256 random bits from the operating system, written as 64 lowercase hex digits.
//! A key is a capability (whoever holds it can read the job), so it must not be guessable:
//! unlike the thesis's hash of a timestamp and a user name, it carries no information at all.

use std::fmt;

/// Hex digits in a key.
const KEY_HEX_LEN: usize = 64;

/// A job's key.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct JobKey(String);

impl JobKey {
    /// A new random key (256 bits from the OS's random source).
    pub fn generate() -> Result<Self, getrandom::Error> {
        let mut bytes = [0u8; KEY_HEX_LEN / 2];
        getrandom::fill(&mut bytes)?;
        Ok(JobKey(bytes.iter().map(|b| format!("{b:02x}")).collect()))
    }

    /// `text` as a key if it has a key's form (64 lowercase hex digits), else `None`: a
    /// malformed key never reaches the database.
    pub fn parse(text: &str) -> Option<Self> {
        let ok = text.len() == KEY_HEX_LEN && text.bytes().all(|b| b.is_ascii_digit() || (b'a'..=b'f').contains(&b));
        ok.then(|| JobKey(text.to_string()))
    }

    /// The key as text.
    pub fn as_str(&self) -> &str {
        &self.0
    }
}

impl fmt::Display for JobKey {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys_are_random_and_well_formed() {
        let a = JobKey::generate().unwrap();
        let b = JobKey::generate().unwrap();
        assert_ne!(a, b);
        assert_eq!(JobKey::parse(a.as_str()), Some(a.clone()));
        assert!(JobKey::parse(&a.as_str()[1..]).is_none());
        assert!(JobKey::parse(&"A".repeat(64)).is_none());
        assert!(JobKey::parse("../../etc/passwd").is_none());
        assert!(JobKey::parse(&"g".repeat(64)).is_none());
    }
}

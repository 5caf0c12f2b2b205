//! Validation. (lead)

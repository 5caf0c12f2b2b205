//! The CPU relight. HELPER D: implement.

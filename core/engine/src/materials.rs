//! Material edits applied at relight time. HELPER D: implement.

//! AIM acoustic world simulator (work in progress).

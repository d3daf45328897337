//! AIM host tracker (work in progress).

//! Reading and writing measurements: pingcal's own JSON format ([`measurements`]) and
//! DBAT's mark-point and control files ([`dbat`]).

pub mod dbat;
pub mod measurements;

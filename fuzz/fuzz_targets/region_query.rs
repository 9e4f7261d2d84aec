//! A snapshot query's selector parameters (`box=..`, `around=..;radius=..`), parsed by
//! `RegionQuery::parse` as the node's queryable does. Needs the `runtime` feature.
//! The body is `node::untrusted_input::live::region_query`, which the test suite's seeded
//! mutations call too.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| node::untrusted_input::live::region_query(data));

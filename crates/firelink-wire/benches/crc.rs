//! Throughput of the 1394 CRC (must exceed 1 GB/s on one core) and of the
//! packet codec on the sizes the servo cycle uses.
#![allow(missing_docs)]

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use firelink_wire::crc::{crc1394, crc1394_bitwise};
use firelink_wire::packet::{AsyncHeader, NodeId, Packet, PacketRepr, Rcode};
use std::hint::black_box;

fn crc(c: &mut Criterion) {
    let mut group = c.benchmark_group("crc1394");
    for size in [16usize, 268, 2048, 65536] {
        let data: Vec<u8> = (0..size).map(|i| (i * 31 + 7) as u8).collect();
        group.throughput(Throughput::Bytes(size as u64));
        group.bench_with_input(BenchmarkId::new("table16", size), &data, |b, d| {
            b.iter(|| crc1394(black_box(d)))
        });
        if size <= 2048 {
            group.bench_with_input(BenchmarkId::new("bitwise", size), &data, |b, d| {
                b.iter(|| crc1394_bitwise(black_box(d)))
            });
        }
    }
    group.finish();
}

fn codec(c: &mut Criterion) {
    // The hub block read response of 8 QLA1 Rev 8 boards: 265 quadlets.
    let hub = vec![0x5Au8; 265 * 4];
    let repr = PacketRepr::ReadBlockResponse {
        header: AsyncHeader::new(NodeId::local(8), NodeId::local(0), 1),
        rcode: Rcode::Complete,
        extended_tcode: 0,
        data: &hub,
    };
    let mut buf = vec![0u8; repr.buffer_len()];
    let mut group = c.benchmark_group("codec");
    group.throughput(Throughput::Bytes(buf.len() as u64));
    group.bench_function("emit_hub_response_8_boards", |b| {
        b.iter(|| black_box(&repr).emit(black_box(&mut buf)).unwrap())
    });
    repr.emit(&mut buf).unwrap();
    group.bench_function("parse_verify_hub_response_8_boards", |b| {
        b.iter(|| {
            let p = Packet::new_checked(black_box(&buf[..])).unwrap();
            p.verify().unwrap();
            black_box(PacketRepr::parse(&p).unwrap());
        })
    });
    group.finish();
}

criterion_group!(benches, crc, codec);
criterion_main!(benches);

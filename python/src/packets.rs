//! Packet records: decode and encode 1394 packets as JSON, and the 1394
//! CRC (`firelink_host::packet_json`).

use pyo3::prelude::*;
use pyo3::types::PyBytes;

use firelink_host::packet_json::{self, PacketJson};

use crate::args;
use crate::errors::error;
use crate::runs::to_json_text;

/// Decode one packet (with `bridge`, a host->bridge datagram): JSON text of
/// its fields (wrapped by `firelink.decode_packet`).
#[pyfunction]
#[pyo3(signature = (data, bridge=None))]
pub(crate) fn decode_packet_json(
    py: Python<'_>,
    data: &Bound<'_, PyAny>,
    bridge: Option<&Bound<'_, PyAny>>,
) -> PyResult<String> {
    let Ok(data) = args::bytes(data, "data") else {
        return Err(error(
            py,
            "PacketError",
            format!("decode_packet takes bytes, not {}", args::type_name(data)),
        ));
    };
    let bridge = bridge.map_or(Ok(false), |b| args::flag(b, "bridge"))?;
    let record =
        packet_json::decode(&data, bridge).map_err(|e| error(py, "PacketError", e.to_string()))?;
    to_json_text(py, &record)
}

/// Encode the packet whose fields are `json` (JSON text): its bytes.
#[pyfunction]
#[pyo3(signature = (json, bridge=None))]
pub(crate) fn encode_packet_json<'py>(
    py: Python<'py>,
    json: &Bound<'py, PyAny>,
    bridge: Option<&Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyBytes>> {
    let json = args::text(json, "the packet's fields", "JSON text")?;
    let bridge = bridge.map_or(Ok(false), |b| args::flag(b, "bridge"))?;
    let record: PacketJson =
        serde_json::from_str(&json).map_err(|e| error(py, "PacketError", e.to_string()))?;
    let bytes = packet_json::encode(&record, bridge)
        .map_err(|e| error(py, "PacketError", e.to_string()))?;
    Ok(PyBytes::new(py, &bytes))
}

/// The IEEE 1394 CRC-32 of `data` (bytes, bytearray or memoryview).
#[pyfunction]
pub(crate) fn crc1394(data: &Bound<'_, PyAny>) -> PyResult<u32> {
    Ok(firelink_wire::crc::crc1394(&args::bytes(data, "data")?))
}

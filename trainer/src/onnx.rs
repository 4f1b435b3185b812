//! The exported actor as an ONNX model (`policy.onnx`): raw observation in, action mean out,
//! normalisation included, the same function as `policy.pt`. ONNX is protobuf; the few
//! messages an MLP needs are declared here with prost's derive (field numbers from the ONNX
//! IR specification, `onnx/onnx.proto`), so no ONNX crate or code generation is needed. The
//! test `tests/tests/export.rs` loads the file with Python's onnxruntime and compares its
//! actions with the Rust policy's.

use prost::Message;
use tch::{Kind, Tensor};

use crate::export::ExportedActor;
use crate::ppo::NORM_CLIP;
use crate::{Error, Result};

/// ONNX IR version 8 (ONNX 1.10+), read by every current runtime.
const IR_VERSION: i64 = 8;
/// The default-domain operator set the graph uses (Sub, Div, Clip with inputs, Gemm, Elu).
const OPSET: i64 = 17;
/// `TensorProto.DataType.FLOAT`.
const FLOAT: i32 = 1;
/// `AttributeProto.AttributeType.FLOAT` and `INT`.
const ATTR_FLOAT: i32 = 1;
const ATTR_INT: i32 = 2;

#[derive(Clone, PartialEq, Message)]
struct ModelProto {
    #[prost(int64, tag = "1")]
    ir_version: i64,
    #[prost(string, tag = "2")]
    producer_name: String,
    #[prost(string, tag = "3")]
    producer_version: String,
    #[prost(string, tag = "6")]
    doc_string: String,
    #[prost(message, optional, tag = "7")]
    graph: Option<GraphProto>,
    #[prost(message, repeated, tag = "8")]
    opset_import: Vec<OperatorSetIdProto>,
}

#[derive(Clone, PartialEq, Message)]
struct OperatorSetIdProto {
    #[prost(string, tag = "1")]
    domain: String,
    #[prost(int64, tag = "2")]
    version: i64,
}

#[derive(Clone, PartialEq, Message)]
struct GraphProto {
    #[prost(message, repeated, tag = "1")]
    node: Vec<NodeProto>,
    #[prost(string, tag = "2")]
    name: String,
    #[prost(message, repeated, tag = "5")]
    initializer: Vec<TensorProto>,
    #[prost(message, repeated, tag = "11")]
    input: Vec<ValueInfoProto>,
    #[prost(message, repeated, tag = "12")]
    output: Vec<ValueInfoProto>,
}

#[derive(Clone, PartialEq, Message)]
struct NodeProto {
    #[prost(string, repeated, tag = "1")]
    input: Vec<String>,
    #[prost(string, repeated, tag = "2")]
    output: Vec<String>,
    #[prost(string, tag = "3")]
    name: String,
    #[prost(string, tag = "4")]
    op_type: String,
    #[prost(message, repeated, tag = "5")]
    attribute: Vec<AttributeProto>,
}

#[derive(Clone, PartialEq, Message)]
struct AttributeProto {
    #[prost(string, tag = "1")]
    name: String,
    #[prost(float, tag = "2")]
    f: f32,
    #[prost(int64, tag = "3")]
    i: i64,
    #[prost(int32, tag = "20")]
    r#type: i32,
}

#[derive(Clone, PartialEq, Message)]
struct TensorProto {
    #[prost(int64, repeated, tag = "1")]
    dims: Vec<i64>,
    #[prost(int32, tag = "2")]
    data_type: i32,
    #[prost(string, tag = "8")]
    name: String,
    /// Little-endian float32 values, row-major.
    #[prost(bytes = "vec", tag = "9")]
    raw_data: Vec<u8>,
}

#[derive(Clone, PartialEq, Message)]
struct ValueInfoProto {
    #[prost(string, tag = "1")]
    name: String,
    #[prost(message, optional, tag = "2")]
    r#type: Option<TypeProto>,
}

#[derive(Clone, PartialEq, Message)]
struct TypeProto {
    #[prost(message, optional, tag = "1")]
    tensor_type: Option<TensorTypeProto>,
}

#[derive(Clone, PartialEq, Message)]
struct TensorTypeProto {
    #[prost(int32, tag = "1")]
    elem_type: i32,
    #[prost(message, optional, tag = "2")]
    shape: Option<TensorShapeProto>,
}

#[derive(Clone, PartialEq, Message)]
struct TensorShapeProto {
    #[prost(message, repeated, tag = "1")]
    dim: Vec<Dimension>,
}

#[derive(Clone, PartialEq, Message)]
struct Dimension {
    #[prost(oneof = "DimValue", tags = "1, 2")]
    value: Option<DimValue>,
}

#[derive(Clone, PartialEq, prost::Oneof)]
enum DimValue {
    #[prost(int64, tag = "1")]
    DimValue(i64),
    #[prost(string, tag = "2")]
    DimParam(String),
}

fn tensor(name: &str, t: &Tensor) -> Result<TensorProto> {
    let t = t.to_kind(Kind::Float).contiguous();
    let values = Vec::<f32>::try_from(t.flatten(0, -1))?;
    Ok(TensorProto {
        dims: t.size(),
        data_type: FLOAT,
        name: name.into(),
        raw_data: values.iter().flat_map(|v| v.to_le_bytes()).collect(),
    })
}

fn scalar(name: &str, v: f32) -> TensorProto {
    TensorProto {
        dims: vec![],
        data_type: FLOAT,
        name: name.into(),
        raw_data: v.to_le_bytes().to_vec(),
    }
}

fn value_info(name: &str, width: i64) -> ValueInfoProto {
    ValueInfoProto {
        name: name.into(),
        r#type: Some(TypeProto {
            tensor_type: Some(TensorTypeProto {
                elem_type: FLOAT,
                shape: Some(TensorShapeProto {
                    dim: vec![
                        Dimension {
                            value: Some(DimValue::DimParam("batch".into())),
                        },
                        Dimension {
                            value: Some(DimValue::DimValue(width)),
                        },
                    ],
                }),
            }),
        }),
    }
}

fn node(op: &str, inputs: &[&str], output: &str, attribute: Vec<AttributeProto>) -> NodeProto {
    NodeProto {
        input: inputs.iter().map(|s| s.to_string()).collect(),
        output: vec![output.into()],
        name: output.into(),
        op_type: op.into(),
        attribute,
    }
}

/// The actor as an ONNX model's bytes: input `obs` `[batch, obs_dim]`, output `actions`
/// `[batch, act_dim]`, computing `clip((obs - mean) / denom, -10, 10)` through the MLP
/// (Gemm + Elu, none after the last layer) in float32, as [`ExportedActor::forward`].
pub fn actor_model(actor: &ExportedActor, doc: &str) -> Result<Vec<u8>> {
    let layers = &actor.actor.layers;
    let (obs_dim, act_dim) = (
        actor.mean.size()[0],
        layers
            .last()
            .map(|(w, _)| w.size()[0])
            .ok_or_else(|| Error::Config("the actor has no layers".into()))?,
    );
    let mut initializer = vec![
        tensor("obs_mean", &actor.mean)?,
        tensor("obs_denom", &actor.denom)?,
        scalar("clip_min", -NORM_CLIP as f32),
        scalar("clip_max", NORM_CLIP as f32),
    ];
    let mut nodes = vec![
        node("Sub", &["obs", "obs_mean"], "centred", vec![]),
        node("Div", &["centred", "obs_denom"], "scaled", vec![]),
        node("Clip", &["scaled", "clip_min", "clip_max"], "x0", vec![]),
    ];
    let mut x = "x0".to_string();
    for (i, (w, b)) in layers.iter().enumerate() {
        let (wn, bn) = (format!("actor.{i}.weight"), format!("actor.{i}.bias"));
        initializer.push(tensor(&wn, w)?);
        initializer.push(tensor(&bn, b)?);
        let last = i + 1 == layers.len();
        let h = if last {
            "actions".to_string()
        } else {
            format!("h{i}")
        };
        let trans_b = AttributeProto {
            name: "transB".into(),
            i: 1,
            r#type: ATTR_INT,
            ..Default::default()
        };
        nodes.push(node("Gemm", &[&x, &wn, &bn], &h, vec![trans_b]));
        if !last {
            let y = format!("x{}", i + 1);
            let alpha = AttributeProto {
                name: "alpha".into(),
                f: 1.0,
                r#type: ATTR_FLOAT,
                ..Default::default()
            };
            nodes.push(node("Elu", &[&h], &y, vec![alpha]));
            x = y;
        }
    }
    let model = ModelProto {
        ir_version: IR_VERSION,
        producer_name: "gaitsweep".into(),
        producer_version: env!("CARGO_PKG_VERSION").into(),
        doc_string: doc.into(),
        graph: Some(GraphProto {
            node: nodes,
            name: "GaitPolicy".into(),
            initializer,
            input: vec![value_info("obs", obs_dim)],
            output: vec![value_info("actions", act_dim)],
        }),
        opset_import: vec![OperatorSetIdProto {
            domain: String::new(),
            version: OPSET,
        }],
    };
    Ok(model.encode_to_vec())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ppo::Mlp;

    /// The bytes decode back into the graph the actor needs, with every weight exact.
    #[test]
    fn the_model_holds_the_actor_layer_by_layer() {
        let w0 = Tensor::from_slice(&[1.0f32, 2.0, 3.0, 4.0, 5.0, 6.0]).view([2, 3]);
        let b0 = Tensor::from_slice(&[0.5f32, -0.5]);
        let w1 = Tensor::from_slice(&[1.0f32, -1.0]).view([1, 2]);
        let b1 = Tensor::from_slice(&[0.25f32]);
        let actor = ExportedActor {
            actor: Mlp {
                layers: vec![(w0, b0), (w1, b1)],
            },
            mean: Tensor::from_slice(&[0.0f32, 1.0, 2.0]),
            denom: Tensor::from_slice(&[1.0f32, 2.0, 4.0]),
        };
        let bytes = actor_model(&actor, "test").unwrap();
        let m = ModelProto::decode(bytes.as_slice()).unwrap();
        let g = m.graph.unwrap();
        let ops: Vec<&str> = g.node.iter().map(|n| n.op_type.as_str()).collect();
        assert_eq!(ops, ["Sub", "Div", "Clip", "Gemm", "Elu", "Gemm"]);
        assert_eq!(g.node.last().unwrap().output, ["actions"]);
        let w = g
            .initializer
            .iter()
            .find(|t| t.name == "actor.0.weight")
            .unwrap();
        assert_eq!(w.dims, [2, 3]);
        assert_eq!(&w.raw_data[4..8], 2.0f32.to_le_bytes());
        assert_eq!(
            (m.opset_import[0].version, m.ir_version),
            (OPSET, IR_VERSION)
        );
    }
}

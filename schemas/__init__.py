"""Message definitions and their versions (DESIGN.md §2).

from schemas import DrapeMsg, encode, decode, SchemaError
msg = DrapeMsg(level="fine", x=x, generation=3)   # numpy arrays accepted
data = encode(msg); back = decode(data, DrapeMsg); back.x.numpy()
"""

from schemas.arrays import DTYPES, Array, as_array, to_numpy
from schemas.design import DESIGN_SCHEMA, Design
from schemas.messages import (
    MESSAGE_TYPES,
    REGISTRY,
    AdjustMsg,
    AdjustStatusMsg,
    DrapeMsg,
    EditMsg,
    MeshMsg,
    Message,
    PatternMsg,
    PsiMsg,
    RejectedMsg,
    SchemaError,
    SolveRequestMsg,
    SolveResultMsg,
    StatusMsg,
    TryOnMsg,
    decode,
    encode,
    json_schema,
    peek_schema,
    validate,
)
from schemas.topics import TOPICS, Delivery, Topic, topic_spec, type_for_topic

__all__ = [
    "DTYPES",
    "Array",
    "as_array",
    "to_numpy",
    "DESIGN_SCHEMA",
    "Design",
    "MESSAGE_TYPES",
    "REGISTRY",
    "TOPICS",
    "Topic",
    "Delivery",
    "topic_spec",
    "Message",
    "PatternMsg",
    "EditMsg",
    "MeshMsg",
    "PsiMsg",
    "DrapeMsg",
    "StatusMsg",
    "RejectedMsg",
    "SolveRequestMsg",
    "SolveResultMsg",
    "TryOnMsg",
    "AdjustMsg",
    "AdjustStatusMsg",
    "SchemaError",
    "encode",
    "decode",
    "validate",
    "peek_schema",
    "json_schema",
    "type_for_topic",
]

//! Tests of the machine definition: every refusal names its field, every accepted definition
//! simulates.

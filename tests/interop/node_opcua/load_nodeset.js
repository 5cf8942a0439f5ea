// Loads motion-server's NodeSet2 export into node-opcua's address space, after the
// nodesets it requires (node-opcua's standard nodeset, then DI and PLCopen as the OPC
// Foundation publishes them), and browses a typed instance, for
// tests/interop/test_opcua_node.py.
//
// Usage: node load_nodeset.js '<json>' with {di, plcopen, site, namespaceUri, instance,
// analog}. Prints one line "RESULT <json>" with what it found; the Python test judges it.
"use strict";

const { AddressSpace } = require("node-opcua-address-space");
const { generateAddressSpace } = require("node-opcua-address-space/nodeJS");
const { nodesets } = require("node-opcua-nodesets");

const cfg = JSON.parse(process.argv[2]);
const PLCOPEN = "http://PLCopen.org/OpcUa/IEC61131-3/";

function uriOf(addressSpace, node) {
    return addressSpace.getNamespaceUri(node.browseName.namespaceIndex);
}

function targets(node, referenceType) {
    return node
        .findReferencesExAsObject(referenceType)
        .map((n) => n.browseName.name)
        .sort();
}

async function main() {
    const addressSpace = AddressSpace.create();
    try {
        await generateAddressSpace(addressSpace, [nodesets.standard, cfg.di, cfg.plcopen, cfg.site]);
        const ns = addressSpace.getNamespaceIndex(cfg.namespaceUri);
        const plc = addressSpace.getNamespaceIndex(PLCOPEN);
        const instance = addressSpace.findNode(`ns=${ns};s=${cfg.instance}`);
        if (!instance) throw new Error(`no node ${cfg.instance}`);
        const chain = [];
        for (let t = instance.typeDefinitionObj; t; t = t.subtypeOfObj) {
            chain.push([uriOf(addressSpace, t), t.browseName.name]);
        }
        const hasInputVar = addressSpace.findReferenceType("HasInputVar", plc);
        const hasOutputVar = addressSpace.findReferenceType("HasOutputVar", plc);
        const analog = addressSpace.findNode(`ns=${ns};s=${cfg.analog}`);
        const eu = analog.getPropertyByName("EngineeringUnits").readValue().value.value;
        const range = analog.getPropertyByName("EURange").readValue().value.value;
        const model = addressSpace.getNamespace(ns);
        const result = {
            namespaces: addressSpace.getNamespaceArray().map((n) => n.namespaceUri),
            typeChain: chain,
            inputs: targets(instance, hasInputVar),
            outputs: targets(instance, hasOutputVar),
            declaredInputs: targets(instance.typeDefinitionObj, hasInputVar),
            unitId: eu.unitId,
            units: eu.displayName.text,
            range: [range.low, range.high],
            initialValue: analog.readValue().value.value,
            modelVersion: model.version,
            requiredModels: (model._requiredModels || []).map((m) => m.namespaceUri || m.modelUri),
        };
        process.stdout.write(`RESULT ${JSON.stringify(result)}\n`);
    } finally {
        addressSpace.dispose();
    }
}

main().catch((err) => {
    process.stderr.write(`node-opcua nodeset loader failed: ${err && err.stack ? err.stack : err}\n`);
    process.exit(1);
});

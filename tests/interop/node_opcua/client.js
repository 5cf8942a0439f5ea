// A node-opcua client that drives motion-server (manual clock) over the Basic256Sha256
// SignAndEncrypt endpoint with user names, for tests/interop/test_opcua_node.py.
//
// Usage: node client.js '<json>' with {endpoint, namespaceUri, pki, admin: [user, pw],
// viewer: [user, pw]}. It switches MSO_1 on for Axis1, jogs it with MAJ_1 (10 mm/s at
// 100 mm/s^2), watches MAJ_1.IP by subscription, tries refused writes, and prints one
// line "RESULT <json>" with what it saw; the Python test judges the values.
"use strict";

const {
    OPCUAClient,
    MessageSecurityMode,
    SecurityPolicy,
    UserTokenType,
    AttributeIds,
    DataType,
    ClientSubscription,
    ClientMonitoredItem,
    TimestampsToReturn,
} = require("node-opcua-client");
const { OPCUACertificateManager } = require("node-opcua-certificate-manager");

const cfg = JSON.parse(process.argv[2]);

async function connect(certificateManager) {
    const client = OPCUAClient.create({
        applicationName: "motion-server node-opcua interop",
        applicationUri: "urn:motion-server:node-opcua-interop",
        securityMode: MessageSecurityMode.SignAndEncrypt,
        securityPolicy: SecurityPolicy.Basic256Sha256,
        endpointMustExist: false,
        connectionStrategy: { maxRetry: 0, initialDelay: 100, maxDelay: 200 },
        clientCertificateManager: certificateManager,
    });
    await client.connect(cfg.endpoint);
    return client;
}

class Tags {
    constructor(session, ns) {
        this.session = session;
        this.ns = ns;
    }
    id(name) {
        return `ns=${this.ns};s=${name}`;
    }
    async read(name) {
        const dv = await this.session.read({ nodeId: this.id(name), attributeId: AttributeIds.Value });
        if (!dv.statusCode.isGood()) throw new Error(`read ${name}: ${dv.statusCode.name}`);
        return dv.value.value;
    }
    // the status code's name ("Good", "BadTypeMismatch", ...)
    async write(name, value, dataType) {
        const code = await this.session.write({
            nodeId: this.id(name),
            attributeId: AttributeIds.Value,
            value: { value: { dataType, value } },
        });
        return code.name;
    }
    async mustWrite(name, value, dataType) {
        const code = await this.write(name, value, dataType);
        if (code !== "Good") throw new Error(`write ${name} = ${value}: ${code}`);
    }
    // manual clock: Clock.Step is answered once its cycles ran
    async step(cycles) {
        await this.mustWrite("Clock.StepCycles", cycles, DataType.UInt32);
        await this.mustWrite("Clock.Step", false, DataType.Boolean);
        await this.mustWrite("Clock.Step", true, DataType.Boolean);
    }
    // one scan with the rung false, then the rising edge
    async trigger(inst) {
        await this.mustWrite(`Instructions.${inst}.Execute`, false, DataType.Boolean);
        await this.step(1);
        await this.mustWrite(`Instructions.${inst}.Execute`, true, DataType.Boolean);
    }
}

async function session(client, [userName, password]) {
    const s = await client.createSession({ type: UserTokenType.UserName, userName, password });
    const namespaces = await s.readNamespaceArray();
    const ns = namespaces.indexOf(cfg.namespaceUri);
    if (ns < 0) throw new Error(`namespace ${cfg.namespaceUri} not in ${namespaces}`);
    return [s, new Tags(s, ns)];
}

function waitFor(predicate, ms) {
    return new Promise((resolve, reject) => {
        const t0 = Date.now();
        const poll = () => {
            if (predicate()) return resolve(true);
            if (Date.now() - t0 > ms) return reject(new Error("timed out waiting"));
            setTimeout(poll, 10);
        };
        poll();
    });
}

async function main() {
    const certificateManager = new OPCUACertificateManager({
        rootFolder: cfg.pki,
        automaticallyAcceptUnknownCertificate: true,
    });
    await certificateManager.initialize();
    const result = {};
    const client = await connect(certificateManager);
    result.securityPolicy = client.securityPolicy;
    result.securityMode = MessageSecurityMode[client.securityMode];
    try {
        const [admin, tags] = await session(client, cfg.admin);
        result.cycleBefore = await tags.read("Clock.Cycle");

        await tags.mustWrite("Instructions.MSO_1.Axis", 1, DataType.Int32);
        await tags.trigger("MSO_1");
        await tags.step(1);
        result.msoDN = await tags.read("Instructions.MSO_1.DN");
        result.msoER = await tags.read("Instructions.MSO_1.ER");

        const seenIP = [];
        const sub = ClientSubscription.create(admin, {
            requestedPublishingInterval: 20,
            requestedLifetimeCount: 600,
            requestedMaxKeepAliveCount: 20,
            maxNotificationsPerPublish: 100,
            publishingEnabled: true,
            priority: 1,
        });
        const item = ClientMonitoredItem.create(
            sub,
            { nodeId: tags.id("Instructions.MAJ_1.IP"), attributeId: AttributeIds.Value },
            { samplingInterval: 0, discardOldest: true, queueSize: 10 },
            TimestampsToReturn.Both
        );
        item.on("changed", (dv) => seenIP.push(dv.value.value));
        await waitFor(() => seenIP.length > 0, 10000); // the initial value

        await tags.mustWrite("Instructions.MAJ_1.Axis", 1, DataType.Int32);
        await tags.mustWrite("Instructions.MAJ_1.Speed", 10.0, DataType.Float);
        await tags.mustWrite("Instructions.MAJ_1.AccelRate", 100.0, DataType.Float);
        await tags.trigger("MAJ_1");
        await tags.step(1);
        result.majDN = await tags.read("Instructions.MAJ_1.DN");
        result.majIP = await tags.read("Instructions.MAJ_1.IP");
        await tags.step(99);
        result.position = await tags.read("Axes.Axis1.CommandPosition");
        result.velocity = await tags.read("Axes.Axis1.CommandVelocity");
        result.cycleAfter = await tags.read("Clock.Cycle");
        await waitFor(() => seenIP.includes(true), 10000);
        result.seenIP = seenIP;
        await sub.terminate();

        result.wrongType = await tags.write("Instructions.MAJ_1.Speed", 7.0, DataType.Double);
        result.output = await tags.write("Instructions.MAJ_1.DN", false, DataType.Boolean);
        result.speedAfterRefused = await tags.read("Instructions.MAJ_1.Speed");
        await admin.close();

        const [viewer, vtags] = await session(client, cfg.viewer);
        result.viewerReads = await vtags.read("Instructions.MSO_1.DN");
        result.viewerWrite = await vtags.write("Instructions.MAJ_1.Execute", false, DataType.Boolean);
        await viewer.close();

        try {
            await client.createSession({
                type: UserTokenType.UserName,
                userName: cfg.admin[0],
                password: "not-the-password",
            });
            result.wrongPassword = "accepted";
        } catch (err) {
            result.wrongPassword = "refused";
        }
    } finally {
        await client.disconnect();
        await certificateManager.dispose();
    }
    process.stdout.write(`RESULT ${JSON.stringify(result)}\n`);
}

main().catch((err) => {
    process.stderr.write(`node-opcua client failed: ${err && err.stack ? err.stack : err}\n`);
    process.exit(1);
});
